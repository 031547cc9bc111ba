"""Physics oracles for the bicycle model with Fiala tyres (thesis App. A.2.1)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sims.driving import BicycleModel, VehicleParams, fiala_lateral_force

MODEL = BicycleModel()
PARAMS = MODEL.params


def _simulate(state, delta, force, seconds, dt=0.01, substeps=1):
    states = [state]
    for _ in range(round(seconds / dt)):
        state = MODEL.step(state, delta, force, dt, substeps)
        states.append(state)
    return np.array(states)


def _fit_circle_radius(xs: np.ndarray, ys: np.ndarray) -> float:
    """Algebraic (Kasa) least-squares circle fit."""
    a = np.column_stack([2 * xs, 2 * ys, np.ones_like(xs)])
    (cx, cy, c), *_ = np.linalg.lstsq(a, xs**2 + ys**2, rcond=None)
    return float(np.sqrt(c + cx**2 + cy**2))


def test_fiala_force_is_linear_at_small_slip_and_saturates_c1() -> None:
    c, f_max = 56.4, 16.0
    t_small = 1e-4
    assert fiala_lateral_force(t_small, c, f_max) == pytest.approx(-c * t_small, rel=1e-3)
    limit = 3 * f_max / c
    below = fiala_lateral_force(limit * (1 - 1e-6), c, f_max)
    assert below == pytest.approx(-f_max, rel=1e-9)  # continuous at the sliding limit
    slope = (fiala_lateral_force(limit * (1 - 1e-3), c, f_max) - below) / (limit * 1e-3)
    assert abs(slope) < 1e-2 * c  # and C1: zero slope at the limit
    assert fiala_lateral_force(2 * limit, c, f_max) == -f_max
    assert fiala_lateral_force(-2 * limit, c, f_max) == f_max
    forces = [fiala_lateral_force(t, c, f_max) for t in np.linspace(0, 2 * limit, 200)]
    assert np.all(np.diff(forces) <= 1e-12)  # monotone, never beyond the friction limit
    assert fiala_lateral_force(0.3, c, 0.0) == 0.0


def test_params_static_loads_and_validation() -> None:
    assert PARAMS.front_load + PARAMS.rear_load == pytest.approx(PARAMS.mass * 9.81)
    assert PARAMS.front_load == pytest.approx(12.10, abs=0.02)  # aa_simulation rccar.yml
    with pytest.raises(ValueError, match="mass"):
        VehicleParams(mass=-1.0)
    with pytest.raises(ValueError, match="max_steer"):
        VehicleParams(max_steer=2.0)


def test_bicycle_zero_steering_goes_straight_and_speed_follows_force() -> None:
    force, v0, seconds = 4.0, 1.0, 3.0
    states = _simulate((0.0, 0.0, 0.0, v0, 0.0, 0.0), 0.0, force, seconds)
    t = np.arange(len(states)) * 0.01
    rate = PARAMS.drag_coefficient / PARAMS.mass
    terminal = force / PARAMS.drag_coefficient
    expected_v = terminal + (v0 - terminal) * np.exp(-rate * t)  # m dv/dt = F - c v
    expected_x = terminal * t + (v0 - terminal) * (1 - np.exp(-rate * t)) / rate
    np.testing.assert_allclose(states[:, 3], expected_v, rtol=1e-8)
    np.testing.assert_allclose(states[:, 0], expected_x, rtol=1e-7)
    assert np.all(states[:, [1, 2, 4, 5]] == 0.0)


def test_bicycle_brakes_to_a_stop_without_reversing() -> None:
    states = _simulate((0.0, 0.0, 0.0, 2.0, 0.0, 0.0), 0.3, -PARAMS.max_brake_force, 3.0)
    assert np.all(np.isfinite(states))
    assert states[-1, 3] == pytest.approx(0.0, abs=1e-3)
    assert states[:, 3].min() > -1e-6


def test_bicycle_starts_from_standstill_on_the_kinematic_model() -> None:
    delta = 0.3
    states = _simulate((0.0, 0.0, 0.0, 0.0, 0.0, 0.0), delta, 0.5, 1.0, dt=0.05, substeps=4)
    assert np.all(np.isfinite(states))
    speed = np.hypot(states[:, 3], states[:, 4])
    kinematic = speed < PARAMS.blend_speed_low
    assert kinematic[-1] and states[-1, 3] > 0.1  # still slow, but moving
    yaw_rate = states[:, 3] * math.tan(delta) / PARAMS.wheelbase  # r = v_x tan(delta) / L
    np.testing.assert_allclose(states[kinematic, 5][5:], yaw_rate[kinematic][5:], atol=0.02)
    np.testing.assert_allclose(states[kinematic, 4], PARAMS.cg_to_rear * states[kinematic, 5],
                               atol=0.01)


@pytest.mark.parametrize("speed", [0.3, 1.0])  # kinematic blend regime and dynamic regime
def test_bicycle_low_speed_turn_radius_is_kinematic(speed: float) -> None:
    delta = 0.2
    state = (0.0, 0.0, 0.0, speed, 0.0, 0.0)
    force = PARAMS.drag_coefficient * speed
    states = _simulate(state, delta, force, 12.0)[300:]  # drop the transient
    rear_x = states[:, 0] - PARAMS.cg_to_rear * np.cos(states[:, 2])
    rear_y = states[:, 1] - PARAMS.cg_to_rear * np.sin(states[:, 2])
    radius = _fit_circle_radius(rear_x, rear_y)
    expected = PARAMS.wheelbase / math.tan(delta)
    assert radius == pytest.approx(expected, rel=0.05)


def test_bicycle_high_speed_full_steering_saturates_tyre_and_drifts() -> None:
    delta, speed = PARAMS.max_steer, 5.0
    force = PARAMS.drag_coefficient * speed
    states = _simulate((0.0, 0.0, 0.0, speed, 0.0, 0.0), delta, force, 0.6)
    tyres = [MODEL.tyre_forces(s[3], s[4], s[5], delta, force) for s in states]
    front_peak = max(abs(t["fy_front"]) for t in tyres)
    mu_fz_front = PARAMS.friction * PARAMS.front_load
    assert front_peak == pytest.approx(mu_fz_front, rel=1e-12)  # saturated at mu F_zf
    assert all(abs(t["fy_rear"]) <= t["fy_rear_max"] + 1e-9 for t in tyres)
    side_slip = np.arctan2(states[:, 4], states[:, 3])
    growing = side_slip[8:38]  # after the first 0.08 s in which the front bites
    assert np.all(np.diff(growing) < 0)  # tail slides out: side slip grows in magnitude
    assert side_slip.min() < -0.4

    # the same steering at low speed keeps the tyres in their linear-ish range
    slow = _simulate((0.0, 0.0, 0.0, 1.0, 0.0, 0.0), delta, PARAMS.drag_coefficient, 0.6)
    slow_tyres = [MODEL.tyre_forces(s[3], s[4], s[5], delta, 1.0) for s in slow[30:]]
    assert max(abs(t["fy_front"]) for t in slow_tyres) < 0.5 * mu_fz_front
    assert np.arctan2(slow[:, 4], slow[:, 3]).min() > -0.05


def test_rear_lateral_capacity_is_derated_by_the_friction_circle() -> None:
    mu_fz = PARAMS.friction * PARAMS.rear_load
    drive = 0.8 * mu_fz
    custom = BicycleModel(VehicleParams(max_drive_force=2 * mu_fz))
    tyres = custom.tyre_forces(3.0, -3.0, 0.0, 0.0, drive)
    assert tyres["fy_rear_max"] == pytest.approx(0.6 * mu_fz)
    assert tyres["fy_rear"] == pytest.approx(0.6 * mu_fz)  # fully sliding at 45 degrees
    assert custom.tyre_forces(3.0, 0.0, 0.0, 0.0, 3 * mu_fz)["fx_rear"] == pytest.approx(mu_fz)


def test_bicycle_step_is_deterministic_and_substeps_converge() -> None:
    state = (0.1, -0.2, 0.3, 4.0, 0.2, 1.0)
    a = MODEL.step(state, 0.4, 6.0, 0.05, 4)
    assert a == MODEL.step(state, 0.4, 6.0, 0.05, 4)
    fine = MODEL.step(state, 0.4, 6.0, 0.05, 32)
    np.testing.assert_allclose(a, fine, atol=1e-4)
    assert MODEL.step(state, 10.0, 6.0, 0.05, 4) == MODEL.step(state, PARAMS.max_steer, 6.0,
                                                                0.05, 4)


def _rates_from_the_definitions(v_x, v_y, r, delta, force):
    """The blended body rates (module docstring of sims/driving/vehicle.py) composed from the
    model's definitions: ``tyre_forces`` (Fiala axles, the rear derated by the friction
    circle, the longitudinal force), ``blend_weight`` and the kinematic model."""
    p = PARAMS
    tyres = MODEL.tyre_forces(v_x, v_y, r, delta, force)
    drive = tyres["fx_rear"] - p.drag_coefficient * v_x
    fyf, fyr = tyres["fy_front"], tyres["fy_rear"]
    dynamic = ((drive - fyf * math.sin(delta)) / p.mass + r * v_y,
               (fyf * math.cos(delta) + fyr) / p.mass - r * v_x,
               (p.cg_to_front * fyf * math.cos(delta) - p.cg_to_rear * fyr) / p.yaw_inertia)
    r_kin = v_x * math.tan(delta) / p.wheelbase
    kinematic = (drive / p.mass, (p.cg_to_rear * r_kin - v_y) / p.kinematic_time_constant,
                 (r_kin - r) / p.kinematic_time_constant)
    lam = MODEL.blend_weight(v_x, v_y)
    return tuple(lam * d + (1.0 - lam) * k for d, k in zip(dynamic, kinematic, strict=True))


def test_the_written_out_rates_are_the_models_definitions() -> None:
    """Oracle: the RK4 stage's rates (written out in one function for speed) equal the model
    composed from its definitions, at random states across the blend (kinematic, blended,
    dynamic), both tyre saturations, braking and reversing. An edit to one of the two that
    the other does not mirror fails here."""
    rng = np.random.default_rng(3)
    for _ in range(2000):
        v_x = float(rng.choice([rng.uniform(-0.5, 0.2), rng.uniform(0.2, 0.8),
                                rng.uniform(0.8, 8.0)]))
        v_y, r = (float(x) for x in rng.normal(0.0, [0.6, 1.5]))
        delta = float(rng.uniform(-PARAMS.max_steer, PARAMS.max_steer))
        force = float(rng.uniform(-2.0, 2.0) * PARAMS.friction * PARAMS.rear_load)
        written = MODEL._body_rates(v_x, v_y, r, delta, math.cos(delta), math.sin(delta),
                                    math.tan(delta), force)
        np.testing.assert_allclose(written, _rates_from_the_definitions(v_x, v_y, r, delta,
                                                                        force),
                                   rtol=1e-9, atol=1e-9)
