"""The consistency findings read as sentences: a table is named without a broken
possessive ("table 'table2''s") and with a verb that agrees."""

from __future__ import annotations

import pytest

from pmdc_bayes import closed_form, load_session
from pmdc_bayes.paper.consistency import consistency_checks


@pytest.mark.parametrize("name", ["demo", "paper"])
def test_consistency_sentences_name_a_table_without_a_broken_possessive(name):
    session = load_session(name)
    findings = consistency_checks(session, closed_form(session))["findings"]
    text = " ".join(findings)
    assert "''s" not in text and "'s speeds" not in text
    if name == "demo":
        assert "the rows of table 'table2' rise at" in text
        assert "put the speeds of the rows of table 'table2' " in text
