"""The enabling switch's silence is counted in time the server could have heard an answer:
a busy server's late loop never makes a present page count as gone, and a gone page on an
idle server is silent `SILENT_S` after its last answer (`web.heartbeat.SilenceClock`)."""

from __future__ import annotations

from web.heartbeat import PING_S, SILENT_S, SilenceClock


def _ticks(clock: SilenceClock, start: float, n: int, late: float) -> float:
    """n ticks of the pinging loop, each `late` s behind its period; the last tick's time."""
    now = start
    for _ in range(n):
        now += PING_S + late
        clock.server_late(late)
    return now


def _longest_silence(late: float, answer_every: float, seconds: float = 5.0) -> float:
    """The longest `silent_for` the loop sees when each tick runs `late` s behind its period
    and the page's answers are handled every `answer_every` s."""
    clock, now, next_answer, worst = SilenceClock(0.0), 0.0, answer_every, 0.0
    while now < seconds:
        now += PING_S + late
        clock.server_late(late)
        if now >= next_answer:
            clock.answered(now)
            next_answer += answer_every
        worst = max(worst, clock.silent_for(now))
    return worst


def test_a_busy_server_does_not_count_its_own_lateness_as_the_pages_silence():
    # A starved machine: the loop 0.1 s late on every tick (no single stall), the page's
    # answers handled every 0.6 s - more than SILENT_S of wall time between them ...
    assert 0.6 > SILENT_S
    # ... but half of it the server could not have heard anything: present throughout.
    assert _longest_silence(late=0.1, answer_every=0.6) <= SILENT_S
    # The same gaps on a server that keeps its period are the page's own: silent.
    assert _longest_silence(late=0.0, answer_every=0.6) > SILENT_S


def test_a_gone_page_on_an_idle_server_is_silent_after_silent_s():
    clock = SilenceClock(0.0)
    n = int(SILENT_S / PING_S)
    assert clock.silent_for(_ticks(clock, 0.0, n - 1, 0.0)) < SILENT_S
    assert clock.silent_for(_ticks(clock, 0.0, n + 1, 0.0)) > SILENT_S


def test_early_ticks_do_not_lend_time():
    """A tick before its period (a coarse timer) owes nothing: the page is not given less."""
    clock = SilenceClock(0.0)
    clock.server_late(-0.05)
    assert clock.owed == 0.0
