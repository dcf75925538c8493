"""Small helpers shared by the tests."""

from __future__ import annotations


def printed_metrics(text: str) -> dict[str, float]:
    """``name value unit`` lines (``simulate --metrics``, ``fuzzyservo metrics``) as a dict."""
    out = {}
    for line in text.splitlines():
        parts = line.split()
        if len(parts) >= 2:
            try:
                out[parts[0]] = float(parts[1])
            except ValueError:
                continue
    return out
