"""Every departure the report lists, and those of the schemes beside the paper's (Woo et al.),
is explained in docs/model.md."""

from __future__ import annotations

from pathlib import Path

from fuzzyservo.paper.departures import DEPARTURES, WOO_DEPARTURES

DOCS = Path(__file__).resolve().parents[2] / "docs" / "model.md"


def test_each_departure_topic_is_documented() -> None:
    text = DOCS.read_text(encoding="utf-8")
    missing = [d.topic for d in DEPARTURES + WOO_DEPARTURES if f"**{d.topic}**" not in text]
    assert not missing, f"docs/model.md does not explain: {missing}"


def test_departures_are_complete_records() -> None:
    every = DEPARTURES + WOO_DEPARTURES
    assert len({d.topic for d in every}) == len(every)
    for d in every:
        assert d.paper and d.ours and d.reason, d.topic
