"""The page's runner runs only the newest request (fuzzyservo.app.latest)."""

from __future__ import annotations

import threading

from fuzzyservo.app import Latest


def test_a_request_replaced_before_its_run_is_dropped_and_a_stale_result_not_shown() -> None:
    gate = threading.Event()
    started = threading.Event()
    ran: list[int] = []
    shown: list[tuple[int, int | BaseException]] = []

    def work(x: int) -> int:
        ran.append(x)
        if x == 1:
            started.set()
            assert gate.wait(10)
        return 10 * x

    latest: Latest[int, int] = Latest(work, lambda seq, res: shown.append((seq, res)))
    assert latest.submit(1) == 1
    assert started.wait(10)  # request 1 is running
    for x in (2, 3, 4):  # arrive while it runs: 2 and 3 are replaced before their run
        latest.submit(x)
    gate.set()
    assert latest.wait_idle(10)
    assert ran == [1, 4]
    # 1's result came when 4 was the newest: stale, not delivered
    assert shown == [(4, 40)]
    stats = latest.stats()
    assert (stats.submitted, stats.ran, stats.dropped, stats.stale_results) == (4, 2, 2, 1)


def test_an_error_is_delivered_as_the_result() -> None:
    shown: list[object] = []

    def work(x: int) -> int:
        raise ValueError(f"bad {x}")

    latest: Latest[int, int] = Latest(work, lambda seq, res: shown.append(res))
    latest.submit(7)
    assert latest.wait_idle(10)
    assert len(shown) == 1 and isinstance(shown[0], ValueError) and str(shown[0]) == "bad 7"


def test_requests_one_after_another_all_run_in_order() -> None:
    shown: list[int] = []
    latest: Latest[int, int] = Latest(lambda x: x, lambda seq, res: shown.append(res))
    for x in range(5):
        latest.submit(x)
        assert latest.wait_idle(10)
    assert shown == [0, 1, 2, 3, 4]
