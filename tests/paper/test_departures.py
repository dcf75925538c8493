"""Every departure the report lists is explained in docs/model.md."""

from __future__ import annotations

from pathlib import Path

from fuzzyservo.paper.departures import DEPARTURES

DOCS = Path(__file__).resolve().parents[2] / "docs" / "model.md"


def test_each_departure_topic_is_documented() -> None:
    text = DOCS.read_text(encoding="utf-8")
    missing = [d.topic for d in DEPARTURES if f"**{d.topic}**" not in text]
    assert not missing, f"docs/model.md does not explain: {missing}"


def test_departures_are_complete_records() -> None:
    assert len({d.topic for d in DEPARTURES}) == len(DEPARTURES)
    for d in DEPARTURES:
        assert d.paper and d.ours and d.reason, d.topic
