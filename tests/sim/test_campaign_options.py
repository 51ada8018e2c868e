"""Robustness options of campaigns: other bases, scaled sensor noise; tails and seeds fixed."""

from __future__ import annotations

import pytest

from sim_worker.campaign import fleet_for, run_campaign


def test_noise_scale_multiplies_sensor_noise_only() -> None:
    nominal, noisy = fleet_for("verification", 2), fleet_for("verification", 2, noise_scale=2.0)
    assert [a.tail for a in nominal] == [a.tail for a in noisy]
    for a, b in zip(nominal, noisy, strict=True):
        assert a.seed == b.seed
        for pos in a.ema:
            sa, sb = a.ema[pos].sensors, b.ema[pos].sensors
            assert sb.current_noise_a == 2 * sa.current_noise_a
            assert sb.voltage_noise_v == 2 * sa.voltage_noise_v
            assert sb.lvdt_noise_m == 2 * sa.lvdt_noise_m
            assert sb.current_offset_a == sa.current_offset_a
            assert a.ema[pos].motor == b.ema[pos].motor


def test_bases_replace_the_climate_mix() -> None:
    mix = fleet_for("design", 1)
    assert [a.base for a in mix].count("Turin") == 4
    hot = fleet_for("design", 1, bases=("Abu Dhabi",))
    assert {a.base for a in hot} == {"Abu Dhabi"}
    assert [a.seed for a in hot] == [a.seed for a in mix]


def test_unknown_base_is_refused(tmp_path) -> None:
    with pytest.raises(ValueError, match="bases"):
        run_campaign("design", tmp_path, seed=1, bases=("Atlantis",), progress=False)


@pytest.mark.parametrize("bad", [0, -3, 2.5, True])
def test_render_every_must_be_a_positive_int(tmp_path, bad) -> None:
    with pytest.raises(ValueError, match="render_every"):
        run_campaign("design", tmp_path, seed=1, render_every=bad, progress=False)
