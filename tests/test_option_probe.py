"""FasterOption: measure each way once, keep the faster, re-measure when the load changes."""

from __future__ import annotations

from semdp.algos.helpers.option_probe import FasterOption


def _drive(probe: FasterOption, times: dict[bool, list[float]], epochs: int) -> list[bool]:
    used = []
    for k in range(epochs):
        option = probe.choose()
        used.append(option)
        probe.record(option, times[option][min(k, len(times[option]) - 1)])
    return used


def test_measures_both_then_keeps_the_faster() -> None:
    used = _drive(FasterOption(reprobe_every=100), {False: [2.0], True: [1.0]}, 6)
    assert used == [False, True, True, True, True, True]
    used = _drive(FasterOption(reprobe_every=100), {False: [1.0], True: [2.0]}, 5)
    assert used == [False, True, False, False, False]


def test_leaves_the_kept_way_when_it_gets_slower_than_the_other_was() -> None:
    # the helper wins until epoch 4, then the machine gets busy and it takes 3x as long
    helper = [1.0, 1.0, 1.0, 1.0, 3.0, 3.0, 3.0, 3.0, 3.0]
    used = _drive(FasterOption(reprobe_every=100), {False: [2.0], True: helper}, 9)
    assert used[:5] == [False, True, True, True, True]
    assert used[5] is False and all(u is False for u in used[6:])
    # a load that slows both ways alike changes nothing
    both = {False: [2.0, 2.0, 4.0, 4.0, 4.0], True: [1.0, 1.0, 2.0, 2.0, 2.0]}
    assert _drive(FasterOption(reprobe_every=100), both, 5) == [False, True, True, True, True]


def test_periodic_reprobe_and_pinned_choice() -> None:
    used = _drive(FasterOption(reprobe_every=3), {False: [2.0], True: [1.0]}, 10)
    assert used == [False, True, True, False, True, True, False, True, True, False]
    assert set(_drive(FasterOption(allowed=False), {False: [1.0], True: [0.1]}, 4)) == {False}
    probe = FasterOption()
    probe.disallow()
    assert probe.choose() is False


def test_starting_with_the_helper_measures_the_other_way_only_when_it_slows_down() -> None:
    quiet = _drive(FasterOption(first=True), {False: [2.0], True: [1.0, 1.1, 0.95, 1.05]}, 30)
    assert quiet == [True] * 30  # no epoch spent on the slower way
    # the machine gets busy at epoch 4: 3x slower with the helper, then the sync way wins
    busy = [1.0, 1.0, 1.0, 1.0, 3.0, 3.0, 3.0, 3.0]
    used = _drive(FasterOption(first=True, reprobe_every=100), {False: [2.0], True: busy}, 8)
    assert used == [True, True, True, True, True, False, False, False]
    assert _drive(FasterOption(allowed=False, first=True), {False: [1.0], True: [0.1]}, 3) \
        == [False] * 3


def test_idle_core_reads_the_idle_share(monkeypatch) -> None:
    from semdp.algos.helpers import option_probe

    samples = iter([(100.0, 1000.0), (100.0 + 190.0, 1000.0 + 200.0)])  # 95 % idle of 2 CPUs
    monkeypatch.setattr(option_probe, "_cpu_times", lambda: next(samples))
    assert option_probe.idle_core(sample_s=0.0, cpus=2)
    samples = iter([(0.0, 1000.0), (100.0, 1200.0)])  # one of 2 CPUs busy (50 % idle)
    monkeypatch.setattr(option_probe, "_cpu_times", lambda: next(samples))
    assert not option_probe.idle_core(sample_s=0.0, cpus=2)
    assert not option_probe.idle_core(sample_s=0.0, cpus=1)
