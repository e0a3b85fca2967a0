"""The session format: ``session.toml`` and the files it names read, checked and
converted to SI once (:func:`load_session`), the records they become (:class:`Session`,
:class:`Trace`), a channel's identity (:class:`ChannelId`) and the unit tables
(:mod:`.units`).

The public names are imported on first use, so that importing one module does not
import the rest.
"""

from .._lazy import lazy_names

__all__ = ["load_session", "Session", "Trace", "ChannelId", "units"]

_LAZY = {"load_session": ".loader", "Session": ".session", "Trace": ".session",
         "ChannelId": ".channel", "units": ".units"}


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
