"""What the fitted model predicts the sensors read: the traces' currents, speeds and
angles at a θ, and the steady readings with their Jacobian, for the adequacy checks, the
residual tables and the report."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..._x64 import to_device, x64

__all__ = ["Predictions", "RESIDUAL_BATCH"]

RESIDUAL_BATCH = 50  # θ per call of the batched residuals (pointwise likelihood, draws)


class Predictions:
    """The prediction methods of :class:`~pmdc_bayes.inference.model.objective.SessionModel`
    (a mixin: it reads the model's session, experiment, blocks and rig effects)."""

    @x64
    def predict(self, theta):
        """Per trace ``(ia, ω)`` in time order (A, rad/s, as the sensors read them), as
        NumPy arrays."""
        if self.exp is None:
            return []
        ia, w = self._predicted(theta)[:2]
        return list(zip(self.exp.split(ia), self.exp.split(w), strict=True))

    @x64
    def predict_angles(self, theta) -> list:
        """Per trace the angle a position sensor would read (rad, its fitted offset
        included), in time order; None for a trace without one."""
        block = self.blocks[0] if self.exp is not None else None
        if block is None or not block.offsets:
            return [None] * len(self.session.traces)
        angle = self._predicted(theta)[2]
        return [a if tr.position is not None else None
                for tr, a in zip(self.session.traces, self.exp.split(angle), strict=True)]

    def residuals_of_batch(self, thetas, whitened: bool = True) -> list:
        """:meth:`~.objective.SessionModel.padded_residuals` at each θ of ``thetas``
        ``(RESIDUAL_BATCH, P)``: per output ``(residual, σ²)``, a leading axis over the
        θ.  One compiled program per session structure, for the pointwise
        log-likelihood and the predictive draws alike.  The θ are taken one at a time
        (``lax.map``): measured on the demo, that compiles in 1.7 s against 2.9 s for
        a body vectorised over 4 θ, runs as fast, and keeps memory at one θ's."""
        name = "pointwise-residuals" if whitened or not self.coloured else "raw-residuals"
        fn = self.compiled(name, lambda: jax.jit(lambda ts, data: jax.lax.map(
            lambda t: self.padded_residuals(t, data=data, whitened=whitened), ts)))
        return fn(to_device(thetas), self.data)

    @x64
    def predict_draws(self, thetas) -> list:
        """Per trace ``(ia, ω, angle)`` at each θ of ``thetas`` ``(N, P)``, as the
        sensors read them: NumPy arrays ``(N, samples)`` in time order, the angle None
        for a trace without a position sensor; from :meth:`residuals_of_batch` (the
        observation less the residual), :data:`RESIDUAL_BATCH` θ a call."""
        if self.exp is None:
            return []
        thetas = np.asarray(thetas, dtype=float)
        n = thetas.shape[0]
        m = -(-n // RESIDUAL_BATCH) * RESIDUAL_BATCH
        padded = np.concatenate([thetas, np.repeat(thetas[:1], m - n, axis=0)])
        d = self.data["traces"]
        out = {k: [] for k in ("current", "speed", "position")}
        for a in range(0, m, RESIDUAL_BATCH):
            outs = self.residuals_of_batch(padded[a:a + RESIDUAL_BATCH], whitened=False)
            for k, (r, _) in zip(("speed", "current", "position"), outs[:3], strict=True):
                out[k].append(np.asarray(d[k])[None] - np.asarray(r))
        unpad = np.asarray(self.exp.index)
        ia, w, angle = (np.concatenate(out[k])[:n].reshape(n, -1)[:, unpad]
                        for k in ("current", "speed", "position"))
        split = [self.exp.split(x) for x in (ia, w, angle)]
        return [(i, v, a if tr.position is not None else None)
                for tr, i, v, a in zip(self.session.traces, *split, strict=True)]

    @x64
    def beyond_phases(self, theta) -> list:
        """Per trace, the start times (s) of its input segments whose regime changes
        more often at θ than the regime-switching solution follows (its prediction there
        is not exact after the last change it follows)."""
        if self.exp is None:
            return []
        flags = self._predicted(theta)[3]
        seg_trace, t0 = np.asarray(self.exp.seg_trace), np.asarray(self.exp.seg_t0)
        return [t0[(seg_trace == k) & flags] for k in range(len(self.session.traces))]

    @x64
    def steady_with_jacobian(self, theta):
        """The steady readings' ``(ia, ω)`` at θ (shape ``(2, n)``), their Jacobian in θ
        (``(2, n, P)``) and the voltages the driver puts out for them, from one compiled
        program."""
        def run(t, d):
            st = d["steady"]

            def steady(th):
                return jnp.stack(self.steady_at(th, st["v"], st["tl"]))

            return steady(t), jax.jacfwd(steady)(t), self.driven(t, st["v"])

        out = self.compiled("steady", lambda: jax.jit(run))(to_device(theta), self.data)
        return tuple(np.asarray(x) for x in out)

    def _predicted(self, theta):
        """``(ia, ω, angle)`` of every trace in time order, from the trace block's own
        residuals (observation − residual; a channel not logged is 0 there), and per
        segment whether it outran the solution's phases: one compiled program serves
        :meth:`predict`, :meth:`predict_angles` and :meth:`beyond_phases`."""
        block = self.blocks[0]

        def run(t, d):
            t, d = self.switched(t, d), d["traces"]
            r, flags = block.residuals(self, t, d, overflow=True)
            return tuple(d["exp"].unpad(d[k] - x)
                         for k, x in zip(("current", "speed", "position"), (r[1], r[0], r[2]),
                                         strict=True)) + (flags,)

        out = self.compiled("predict", lambda: jax.jit(run))(to_device(theta), self.data)
        return tuple(np.asarray(x) for x in out)
