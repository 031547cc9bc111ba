"""FasterOption: measure each way once, keep the faster, re-measure when the load changes."""

from __future__ import annotations

from semdp.common.option_probe import FasterOption


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
