"""Tests of the jerk-limited planner, the stops and the streamer (real ruckig)."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from ruckig import ControlInterface, InputParameter, Ruckig, Synchronization, Trajectory

from rheo_shaping.planning.plans import (
    DEFAULT_LIMITS,
    MIN_MOVE_M,
    MotionLimits,
    Plan,
    Waypoint,
    plan_waypoints,
    rest_to_rest_time,
)
from rheo_shaping.planning.stopping import (
    TrajectoryStreamer,
    stop_from_state,
    stopping_distance,
    stopping_time,
)

NOMINAL = DEFAULT_LIMITS                        # 1e-3 m/s, 5e-3 m/s^2, 5e-2 m/s^3
FAST = MotionLimits(5e-3, 5e-3, 5e-2)           # 5x the paper's tool speed
RETRACT = MotionLimits(2e-3, 2.5e-3, 2.5e-2)
REL = 1e-6                                      # relative tolerance on the limits
DT = 1e-3                                       # sampling step [s]

START = (0.03, 0.10)
# Movement 4 of the paper (2-step: vertical, 15 s, horizontal, 15 s, retract)
# followed by a 45 deg inclined move; cake wall at x = 0.
MOVEMENT = [
    Waypoint(0.0145, 0.085, 0.0, "approach"),
    Waypoint(0.0145, 0.065, 15.0, "vertical"),
    Waypoint(0.0, 0.065, 15.0, "horizontal"),
    Waypoint(0.03, 0.095, 0.0, "retract"),
    Waypoint(0.03, 0.10, 2.0, "home"),
]


# -- helpers ----------------------------------------------------------------


def check_limits(plan: Plan, limits: MotionLimits, t0: float = 0.0, t1: float | None = None,
                 dt: float = DT) -> tuple[float, float, float]:
    """Dense check of |v|, |a| and the finite-difference |jerk|; returns the peaks."""
    t1 = plan.duration if t1 is None else t1
    t = np.arange(t0, t1 + 2 * dt, dt)
    pos, vel, acc = plan.sample_many(t)
    speed = np.linalg.norm(vel, axis=1)
    amag = np.linalg.norm(acc, axis=1)
    jerk = np.linalg.norm(np.diff(acc, axis=0), axis=1) / dt
    acc_fd = np.linalg.norm(np.diff(vel, axis=0), axis=1) / dt
    assert speed.max() <= limits.v_max * (1 + REL)
    assert amag.max() <= limits.a_max * (1 + REL)
    assert acc_fd.max() <= limits.a_max * (1 + REL) + 1e-12
    assert jerk.max() <= limits.j_max * (1 + REL) + 1e-12
    # the sampler is self-consistent: the position integrates the velocity
    v_mid = np.diff(pos, axis=0) / dt
    v_avg = 0.5 * (vel[1:] + vel[:-1])
    assert np.abs(v_mid - v_avg).max() <= limits.j_max * dt ** 2 + 1e-12
    return float(speed.max()), float(amag.max()), float(jerk.max())


def line_deviation(plan: Plan, seg, n: int = 4001) -> float:
    """Largest distance [m] of the samples of ``seg`` from its nominal line."""
    t = np.linspace(seg.t_start, seg.t_end, n)
    pos, _, _ = plan.sample_many(t)
    a, b = np.asarray(seg.start), np.asarray(seg.end)
    u = (b - a) / np.linalg.norm(b - a)
    rel = pos - a
    return float(np.abs(rel[:, 0] * u[1] - rel[:, 1] * u[0]).max())


def ruckig_segment(p0, p1, limits: MotionLimits) -> Trajectory:
    """Independent ruckig computation of one straight segment."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    u = np.abs(p1 - p0) / np.linalg.norm(p1 - p0)
    c = np.where(u > 0, u, 1.0)
    inp = InputParameter(2)
    inp.current_position, inp.target_position = p0.tolist(), p1.tolist()
    inp.max_velocity = (limits.v_max * c).tolist()
    inp.max_acceleration = (limits.a_max * c).tolist()
    inp.max_jerk = (limits.j_max * c).tolist()
    inp.synchronization = Synchronization.Phase
    traj = Trajectory(2)
    Ruckig(2).calculate(inp, traj)
    return traj


def closed_form_stop(v: float, lim: MotionLimits) -> float:
    a, j = lim.a_max, lim.j_max
    return v / a + a / j if v >= a * a / j else 2 * math.sqrt(v / j)


# -- validation -------------------------------------------------------------


@pytest.mark.parametrize("field", ["v_max", "a_max", "j_max"])
@pytest.mark.parametrize("bad", [0.0, -1e-3, float("nan"), float("inf")])
def test_limits_refuse_bad_values(field, bad):
    kw = dict(v_max=1e-3, a_max=5e-3, j_max=5e-2)
    kw[field] = bad
    with pytest.raises(ValueError) as exc:
        MotionLimits(**kw)
    msg = str(exc.value)
    assert field in msg and repr(bad) in msg and "> 0" in msg


def test_waypoint_validation_and_frozen():
    with pytest.raises(ValueError, match="dwell_s"):
        Waypoint(0.0, 0.0, dwell_s=-1.0)
    with pytest.raises(ValueError, match="Waypoint.x"):
        Waypoint(float("nan"), 0.0)
    wp = Waypoint(0.01, 0.02, 3.0, "a")
    with pytest.raises(dataclasses.FrozenInstanceError):
        wp.x = 1.0  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        NOMINAL.v_max = 1.0  # type: ignore[misc]


# -- plans ------------------------------------------------------------------


@pytest.mark.parametrize("limits", [NOMINAL, FAST], ids=["nominal", "5x"])
def test_limits_hold_on_dense_sampling(limits):
    plan = plan_waypoints(START, MOVEMENT, limits)
    vmax, amax, jmax = check_limits(plan, limits)
    # and they are actually used (cruise at v_max, full acceleration and jerk)
    assert vmax == pytest.approx(limits.v_max, rel=1e-9)
    assert plan.max_speed == pytest.approx(limits.v_max, rel=1e-12)
    assert amax == pytest.approx(limits.a_max, rel=1e-6)
    assert jmax == pytest.approx(limits.j_max, rel=1e-3)


def test_sampler_matches_ruckig_at_time():
    p0, p1 = (0.03, 0.10), (0.011, 0.071)
    plan = plan_waypoints(p0, [Waypoint(*p1)], NOMINAL)
    traj = ruckig_segment(p0, p1, NOMINAL)
    assert plan.duration == traj.duration
    rng = np.random.default_rng(1)
    ts = np.concatenate([rng.uniform(0, traj.duration, 200), [
                        0.05, 0.1, 0.15, traj.duration - 0.05]])
    pos, vel, acc = plan.sample_many(ts)
    for k, t in enumerate(ts):
        p, v, a = traj.at_time(float(t))
        assert np.allclose(pos[k], p, rtol=0, atol=1e-15)
        assert np.allclose(vel[k], v, rtol=0, atol=1e-15)
        assert np.allclose(acc[k], a, rtol=0, atol=1e-15)
        ps, vs, as_ = plan.sample(float(t))
        assert np.array_equal(ps, pos[k]) and np.array_equal(
            vs, vel[k]) and np.array_equal(as_, acc[k])


@pytest.mark.parametrize("angle_deg", [45.0, -45.0, 135.0, 30.0, 89.999, 0.0, 90.0])
def test_straight_line(angle_deg):
    th = math.radians(angle_deg)
    d = 0.02
    end = (START[0] + d * math.cos(th), START[1] + d * math.sin(th))
    plan = plan_waypoints(START, [Waypoint(*end)], NOMINAL)
    (seg,) = plan.segments
    assert line_deviation(plan, seg) < 1e-9
    check_limits(plan, NOMINAL)


def test_45_degree_segment_deviation_and_speed():
    plan = plan_waypoints((0.03, 0.10), [Waypoint(0.01, 0.08, label="inclined")], NOMINAL)
    (seg,) = plan.segments
    assert line_deviation(plan, seg) < 1e-9
    # during cruise the path speed is exactly v_max and both axes move alike
    _, vel, _ = plan.sample(plan.duration / 2)
    assert np.linalg.norm(vel) == pytest.approx(NOMINAL.v_max, rel=1e-12)
    assert vel[0] == pytest.approx(vel[1], rel=1e-12)


def test_rest_at_waypoints_and_exact_dwells():
    plan = plan_waypoints(START, MOVEMENT, NOMINAL)
    kinds = [s.kind for s in plan.segments]
    assert kinds == ["move", "move", "dwell", "move", "dwell", "move", "move", "dwell"]
    labels = [s.label for s in plan.segments]
    assert labels[2] == "vertical:dwell" and labels[1] == "vertical"
    dwell_by_label = {w.label: w.dwell_s for w in MOVEMENT}
    for seg in plan.segments:
        p, v, a = plan.sample(seg.t_end)
        assert np.array_equal(v, [0.0, 0.0]) and np.array_equal(a, [0.0, 0.0])
        assert np.allclose(p, seg.end, rtol=0, atol=1e-12)
        if seg.kind == "dwell":
            assert seg.t_end - \
                seg.t_start == pytest.approx(dwell_by_label[seg.label.split(":")[0]], abs=1e-12)
            ts = np.linspace(seg.t_start, seg.t_end, 101)
            pos, vel, acc = plan.sample_many(ts)
            assert np.all(vel == 0.0) and np.all(acc == 0.0)
            assert np.ptp(pos, axis=0).max() == 0.0
    # segments tile [0, duration]
    assert plan.segments[0].t_start == 0.0
    for s0, s1 in zip(plan.segments, plan.segments[1:]):
        assert s1.t_start == s0.t_end
    assert plan.segments[-1].t_end == plan.duration
    total_dwell = sum(w.dwell_s for w in MOVEMENT)
    moves = sum(s.duration for s in plan.segments if s.kind == "move")
    assert plan.duration == pytest.approx(total_dwell + moves, abs=1e-12)


def test_long_segment_duration_matches_closed_form():
    lim = NOMINAL
    d = 0.03  # >> v*(v/a + a/j) = 3e-4 m: cruise, both acceleration trapezoids
    plan = plan_waypoints((0.0, 0.1), [Waypoint(0.0, 0.1 - d)], lim)
    expected = d / lim.v_max + lim.v_max / lim.a_max + lim.a_max / lim.j_max
    assert expected == pytest.approx(30.3)
    assert plan.duration == pytest.approx(expected, abs=1e-9)
    assert rest_to_rest_time(d, lim) == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize("limits", [NOMINAL, FAST, MotionLimits(1e-3, 5e-2, 5e-2)],
                         ids=["nom", "fast", "v<a2/j"])
@pytest.mark.parametrize("d", [1e-7, 1e-5, 2e-4, 5e-4, 3e-3, 0.05])
def test_rest_to_rest_time_all_regimes(limits, d):
    plan = plan_waypoints((0.0, 0.0), [Waypoint(d / math.sqrt(2), d / math.sqrt(2))], limits)
    assert plan.duration == pytest.approx(rest_to_rest_time(d, limits), rel=1e-9, abs=1e-12)


def test_sampling_outside_and_immutability():
    plan = plan_waypoints(START, MOVEMENT[:2], NOMINAL)
    for t in (-5.0, 0.0):
        p, v, a = plan.sample(t)
        assert np.array_equal(p, START) and not v.any() and not a.any()
    p, v, a = plan.sample(plan.duration + 100)
    assert np.allclose(p, (MOVEMENT[1].x, MOVEMENT[1].z),
                       atol=1e-12) and not v.any() and not a.any()
    pos, vel, _ = plan.sample_many([-1.0, 1e9])
    assert np.array_equal(pos[0], START) and not vel.any()
    with pytest.raises(dataclasses.FrozenInstanceError):
        plan.duration = 1.0  # type: ignore[misc]
    with pytest.raises(ValueError):
        plan._axes[0].p0[0] = 1.0  # read-only arrays


def test_knots_and_arrays():
    plan = plan_waypoints(START, MOVEMENT, NOMINAL)
    k = plan.knots()
    assert k[0] == 0.0 and k[-1] == plan.duration and np.all(np.diff(k) > 0)
    for s in plan.segments:
        if s.kind == "move":
            assert s.t_start in k and s.t_end in k
    assert len(plan.knots(include_phases=True)) > len(k)
    times, pos, vel = plan.to_arrays(0.01)
    assert times[0] == 0.0 and times[-1] == plan.duration
    assert np.all(np.diff(times) > 0) and np.diff(times)[:-1] == pytest.approx(0.01)
    p, v, _ = plan.sample(times[123])
    assert np.array_equal(pos[123], p) and np.array_equal(vel[123], v)


def test_vectorised_sampling_of_120_s_at_1_kHz_matches_the_pointwise_samples():
    """sample_many (the fast path: its speed is measured in benchmarks/bench_simulator.py)
    gives what sample gives, point by point."""
    plan = plan_waypoints(START, MOVEMENT, NOMINAL)
    times = np.arange(0.0, 120.0, 1e-3)
    pos, vel, acc = plan.sample_many(times)
    assert pos.shape == vel.shape == acc.shape == (120000, 2)
    for k in (0, 1, 4567, 60000, 119999):
        p, v, a = plan.sample(times[k])
        assert np.array_equal(pos[k], p) and np.array_equal(vel[k], v)
        assert np.array_equal(acc[k], a)


def test_empty_and_degenerate_plans():
    plan = plan_waypoints(START, [], NOMINAL)
    assert plan.duration == 0.0 and plan.segments == ()
    plan = plan_waypoints(START, [Waypoint(*START, dwell_s=5.0)], NOMINAL)
    assert [s.kind for s in plan.segments] == ["dwell"] and plan.duration == 5.0
    with pytest.raises(ValueError, match="start_xz"):
        plan_waypoints((0.0, float("inf")), [], NOMINAL)


# -- stops ------------------------------------------------------------------


@pytest.mark.parametrize("limits", [NOMINAL, FAST, MotionLimits(5e-3, 5e-2, 5e-2)],
                         ids=["nom", "fast", "no-amax"])
@pytest.mark.parametrize("speed", [5e-3, 1e-3, 4e-4, 1e-5])
@pytest.mark.parametrize("angle_deg", [0.0, 45.0, -120.0])
def test_stop_from_constant_speed_matches_closed_form(limits, speed, angle_deg):
    u = np.array([math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))])
    stop = stop_from_state((0.02, 0.07), speed * u, (0.0, 0.0), limits)
    expected = closed_form_stop(speed, limits)
    assert stop.duration == pytest.approx(expected, abs=1e-6)
    assert stopping_time(speed, limits) == pytest.approx(expected, rel=1e-15)
    travelled = np.asarray(stop.end) - (0.02, 0.07)
    assert float(travelled @ u) == pytest.approx(stopping_distance(speed, limits), rel=1e-9)
    assert abs(travelled[0] * u[1] - travelled[1] * u[0]) < 1e-12       # stays on the line
    _, v, a = stop.sample(stop.duration)
    assert not v.any() and not a.any()
    _, v0, _ = stop.sample(0.0 + 1e-12)
    assert np.allclose(v0, speed * u, atol=1e-12)
    check_limits(stop, MotionLimits(max(speed, 1e-9), limits.a_max,
                 limits.j_max), dt=stop.duration / 2000)


def test_stop_numbers_for_the_cell():
    assert stopping_time(5e-3, NOMINAL) == pytest.approx(1.1, abs=1e-12)
    assert stopping_distance(5e-3, NOMINAL) == pytest.approx(2.75e-3, abs=1e-12)
    assert stopping_time(1e-3, NOMINAL) == pytest.approx(0.3, abs=1e-12)
    assert stopping_time(0.0, NOMINAL) == 0.0
    with pytest.raises(ValueError, match="speed"):
        stopping_time(-1.0, NOMINAL)


@pytest.mark.parametrize("acc_scale", [0.8, -0.8, 1.2, -1.5])
def test_stop_from_accelerating_state(acc_scale):
    lim = NOMINAL
    u = np.array([1.0, -1.0]) / math.sqrt(2)
    v0, a0 = 3e-3 * u, acc_scale * lim.a_max * u
    stop = stop_from_state((0.0, 0.1), v0, a0, lim)
    p, v, a = stop.sample(1e-12)
    assert np.allclose(v, v0, atol=1e-12) and np.allclose(a, a0, atol=1e-9)
    t = np.arange(0, stop.duration + 2 * DT, DT / 10)
    _, vel, acc = stop.sample_many(t)
    assert np.linalg.norm(acc, axis=1).max() <= max(
        lim.a_max, abs(acc_scale) * lim.a_max) * (1 + REL)
    jerk = np.linalg.norm(np.diff(acc, axis=0), axis=1) / (DT / 10)
    assert jerk.max() <= lim.j_max * (1 + REL)
    assert not stop.sample(stop.duration)[1].any()
    # the reconstruction (incl. ruckig's brake pre-profile) matches ruckig
    inp = InputParameter(2)
    inp.control_interface = ControlInterface.Velocity
    inp.synchronization = Synchronization.Phase
    inp.current_position, inp.current_velocity, inp.current_acceleration = [
        0.0, 0.1], v0.tolist(), a0.tolist()
    inp.max_velocity = [1.0, 1.0]
    inp.max_acceleration = (lim.a_max * np.abs(u)).tolist()
    inp.max_jerk = (lim.j_max * np.abs(u)).tolist()
    traj = Trajectory(2)
    Ruckig(2).calculate(inp, traj)
    assert stop.duration == pytest.approx(traj.duration, abs=1e-12)
    for tt in np.linspace(0, traj.duration, 97):
        ps, vs, as_ = stop.sample(float(tt))
        pr, vr, ar = traj.at_time(float(tt))
        assert np.allclose(ps, pr, atol=1e-15) and np.allclose(vs, vr, atol=1e-15)
        if 0 < tt < traj.duration:
            assert np.allclose(as_, ar, atol=1e-15)


def test_stop_from_non_collinear_state_keeps_norm_limits():
    lim = NOMINAL
    stop = stop_from_state((0.0, 0.1), (1e-3, -2e-3), (2e-3, 1e-3), lim)
    t = np.arange(0, stop.duration + DT, DT / 10)
    _, vel, acc = stop.sample_many(t)
    assert np.linalg.norm(acc, axis=1).max() <= lim.a_max * (1 + REL)
    assert (np.linalg.norm(np.diff(acc, axis=0), axis=1) /
            (DT / 10)).max() <= lim.j_max * (1 + REL)
    assert not stop.sample(stop.duration)[1].any()


def test_stop_at_rest_is_empty():
    stop = stop_from_state((0.01, 0.02), (0.0, 0.0), (0.0, 0.0), NOMINAL)
    assert stop.duration == 0.0 and stop.end == (0.01, 0.02)


# -- streamer ---------------------------------------------------------------


def stream(streamer: TrajectoryStreamer, t0: float, t1: float, dt: float = DT):
    ts = np.arange(t0, t1, dt)
    out, states = [], []
    for t in ts:
        out.append(streamer.setpoint(float(t)))
        states.append(streamer.state)
    return (ts, np.array([o[0] for o in out]), np.array([o[1] for o in out]),
            np.array([o[2] for o in out]), states)


def test_streamer_runs_a_plan_to_done():
    plan = plan_waypoints(START, MOVEMENT[:2], FAST)
    s = TrajectoryStreamer(home_xz=START, initial_xz=START)
    assert s.state == "idle"
    assert np.array_equal(s.setpoint(0.0)[0], START)
    s.start(plan, 10.0)
    assert s.state == "running"
    for t in np.linspace(10.0, 10.0 + plan.duration, 37)[:-1]:
        p, v, a = s.setpoint(float(t))
        pp, vp, ap = plan.sample(float(t) - 10.0)
        assert np.array_equal(p, pp) and np.array_equal(v, vp) and np.array_equal(a, ap)
    s.setpoint(10.0 + plan.duration)
    assert s.state == "done"
    with pytest.raises(RuntimeError):
        s.start(plan, 100.0)
    s.reset()
    with pytest.raises(ValueError, match="jump"):
        s.start(plan, 100.0)  # the tool is not at the plan's start


def test_abort_mid_segment_on_fast_plan():
    plan = plan_waypoints(START, MOVEMENT, FAST)
    seg = plan.segments[1]                      # the vertical forced deformation
    t0 = 5.0
    t_abort = t0 + 0.5 * (seg.t_start + seg.t_end)
    home = (0.03, 0.12)
    s = TrajectoryStreamer(home_xz=home, retract_limits=RETRACT, initial_xz=START)
    s.start(plan, t0)
    before = s.setpoint(t_abort - DT)
    s.abort(t_abort, "tension")
    assert s.aborted and s.abort_reason == "tension" and s.state == "stopping"
    # the stop starts from the exact current state of the plan
    p, v, a = s.setpoint(t_abort)
    pp, vp, ap = plan.sample(t_abort - t0)
    assert np.array_equal(p, pp) and np.array_equal(v, vp) and np.array_equal(a, ap)
    assert np.linalg.norm(v) == pytest.approx(FAST.v_max, rel=1e-12)
    assert s.stop_plan.duration == pytest.approx(stopping_time(FAST.v_max, FAST), abs=1e-6)
    assert s.rest_time == pytest.approx(t_abort + 1.1, abs=1e-6)
    # stream the stop at 1 kHz, then the retract, then the hold
    ts, pos, vel, acc, states = stream(s, t_abort, s.rest_time + 60.0)
    ts = np.concatenate([[t_abort - DT], ts])
    pos, vel, acc = (np.vstack([b, x]) for b, x in zip(before, (pos, vel, acc)))
    assert set(states) == {"stopping", "retracting", "holding"}
    assert states == sorted(states, key=["stopping", "retracting", "holding"].index)
    stopping = ts < s.rest_time
    assert np.linalg.norm(vel, axis=1)[stopping].max() <= FAST.v_max * (1 + REL)
    assert np.linalg.norm(acc, axis=1).max() <= FAST.a_max * (1 + REL)
    jerk = np.linalg.norm(np.diff(acc, axis=0), axis=1) / DT
    assert jerk.max() <= FAST.j_max * (1 + REL)
    assert np.linalg.norm(vel, axis=1)[~stopping].max() <= RETRACT.v_max * (1 + REL)
    # at rest at rest_time, where the closed form says
    p_rest, v_rest, a_rest = s.stop_plan.sample(s.stop_plan.duration)
    assert not v_rest.any() and not a_rest.any()
    travelled = np.linalg.norm(np.asarray(p_rest) - pp)
    assert travelled == pytest.approx(stopping_distance(FAST.v_max, FAST), rel=1e-9)
    # never moves on along the old plan: downward progress stops at the rest point
    assert pos[:, 1].min() >= p_rest[1] - 1e-12
    assert pos[:, 1].min() > seg.end[1] + 1e-3
    # then retracts home and holds there; old-plan times do not resurrect it
    assert states[-1] == "holding"
    for t in (t0 + plan.duration, t0 + plan.duration + 1000.0, 0.0):
        p, v, a = s.setpoint(t)
        assert np.allclose(p, home, atol=1e-12) and not v.any() and not a.any()
        assert s.state == "holding"
    # the abort latches
    s.abort(t0 + 1e4, "again")
    assert s.abort_time == t_abort and s.abort_reason == "tension"
    with pytest.raises(RuntimeError):
        s.start(plan, 1e4)
    s.reset()
    assert s.state == "idle" and not s.aborted
    s.start(plan_waypoints(home, [Waypoint(*START)], NOMINAL), 2e4)
    assert s.state == "running"


@pytest.mark.parametrize("frac", [0.3, 0.7, 0.95])
def test_abort_while_accelerating_is_continuous_and_latched(frac):
    """Abort inside the acceleration ramp: the stop continues from the exact
    (accelerating) state, so the streamed jerk never exceeds j_max."""
    plan = plan_waypoints(START, MOVEMENT, FAST)
    seg = plan.segments[1]
    ramp = FAST.v_max / FAST.a_max + FAST.a_max / FAST.j_max      # 1.1 s
    t_abort = seg.t_start + frac * ramp
    s = TrajectoryStreamer()
    s.start(plan, 0.0)
    ts = t_abort - DT * np.arange(200, 0, -1)
    pre = [s.setpoint(float(t)) for t in ts]
    s.abort(t_abort, "tension")
    p, v, a = s.setpoint(t_abort)
    pp, vp, ap = plan.sample(t_abort)
    assert np.linalg.norm(ap) > 0.1 * FAST.a_max                   # really accelerating
    assert np.array_equal(p, pp) and np.array_equal(v, vp) and np.array_equal(a, ap)
    s.abort(t_abort + 0.1, "again")                                 # latched while stopping
    assert s.abort_time == t_abort and s.abort_reason == "tension"
    _, _, vel, acc, states = stream(s, t_abort, s.rest_time + 0.5)
    vel = np.vstack([[x[1] for x in pre], vel])
    acc = np.vstack([[x[2] for x in pre], acc])
    assert np.linalg.norm(vel, axis=1).max() <= FAST.v_max * (1 + REL)
    assert np.linalg.norm(acc, axis=1).max() <= FAST.a_max * (1 + REL)
    assert (np.linalg.norm(np.diff(acc, axis=0), axis=1) / DT).max() <= FAST.j_max * (1 + REL)
    assert states[-1] == "holding" and not vel[-1].any()


def test_a_stop_told_to_hold_ends_at_rest_holding_without_a_retract():
    """hold_after_stop (a planner deactivated mid-run): the stop streamed to its end holds
    there, never retracting, so reset() is taken; before it the stop would retract."""
    plan = plan_waypoints(START, MOVEMENT, FAST)
    t_abort = 0.5 * (plan.segments[1].t_start + plan.segments[1].t_end)
    for hold in (False, True):
        s = TrajectoryStreamer(home_xz=(0.05, 0.12), retract_limits=RETRACT)
        s.start(plan, 0.0)
        s.setpoint(t_abort)
        s.abort(t_abort, "deactivated")
        if hold:
            s.hold_after_stop()
        p_rest, _, _ = s.stop_plan.sample(s.stop_plan.duration)
        _, pos, vel, _, states = stream(s, t_abort, s.rest_time + 5.0)
        if not hold:
            assert states[-1] == "retracting"
            continue
        assert set(states) == {"stopping", "holding"} and not vel[-1].any()
        assert np.allclose(pos[-1], p_rest, atol=1e-12)
        s.reset()
        assert s.state == "idle"
    s.hold_after_stop()                         # outside a stop: nothing changes
    assert s.state == "idle"


def test_abort_during_retract_stops_and_holds():
    plan = plan_waypoints(START, MOVEMENT[:2], FAST)
    s = TrajectoryStreamer(home_xz=(0.05, 0.12), retract_limits=RETRACT)
    s.start(plan, 0.0)
    s.setpoint(plan.duration + 1.0)
    assert s.state == "done"
    s.abort(plan.duration + 1.0)
    s.setpoint(plan.duration + 1.0)
    assert s.state == "retracting"               # done -> zero-length stop -> retract
    with pytest.raises(RuntimeError):
        s.reset()                                # refused while moving
    t_mid = plan.duration + 10.0
    p_mid, v_mid, _ = s.setpoint(t_mid)
    assert np.linalg.norm(v_mid) > 0
    s.abort(t_mid, "second")                      # a second abort during the retract stops it
    assert s.state == "stopping"
    _, _, _, _, states = stream(s, t_mid, t_mid + 5.0)
    assert states[-1] == "holding" and "retracting" not in states
    p_end, v_end, _ = s.setpoint(t_mid + 100.0)
    assert not v_end.any()
    assert np.linalg.norm(
        p_end - p_mid) == pytest.approx(stopping_distance(np.linalg.norm(v_mid), RETRACT),
                                        rel=1e-6)


def test_abort_without_home_holds_where_it_stops():
    plan = plan_waypoints(START, MOVEMENT[:2], NOMINAL)
    s = TrajectoryStreamer()
    s.start(plan, 0.0)
    s.abort(10.0)
    p, _, _ = s.setpoint(100.0)
    assert s.state == "holding"
    assert np.allclose(p, s.stop_plan.end, atol=0)
    s2 = TrajectoryStreamer(initial_xz=START)
    s2.abort(1.0)
    assert s2.state == "holding" and np.array_equal(s2.setpoint(2.0)[0], START)


# -- property ----------------------------------------------------------------

coord = st.floats(-0.05, 0.05, allow_nan=False)
waypoint = st.builds(Waypoint, coord, coord, st.floats(0.0, 3.0) | st.just(0.0))
limits_st = st.builds(MotionLimits, st.floats(1e-4, 5e-3),
                      st.floats(1e-3, 5e-2), st.floats(1e-2, 1.0))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(start=st.tuples(coord, coord), wps=st.lists(waypoint, min_size=1, max_size=4),
       lim=limits_st)
def test_property_random_waypoints(start, wps, lim):
    plan = plan_waypoints(start, wps, lim)
    segs = plan.segments
    p_prev = np.asarray(start)
    expected = 0.0
    k = 0
    for wp in wps:
        d = float(np.linalg.norm(wp.xz - p_prev))
        if abs(d - MIN_MOVE_M) < 1e-15:   # on the threshold round-off decides
            moved = k < len(segs) and segs[k].kind == "move" and segs[k].end == (wp.x, wp.z)
        else:
            moved = d > MIN_MOVE_M
        if moved:
            seg = segs[k]
            k += 1
            assert seg.kind == "move"
            # ruckig's time precision is ~1e-11 s at nanometre distances
            assert seg.duration == pytest.approx(rest_to_rest_time(d, lim), rel=1e-9, abs=1e-9)
            if d > 1e-9:
                assert line_deviation(plan, seg, n=501) < 1e-9
            expected += seg.duration
            p_prev = wp.xz
        if wp.dwell_s > 0:
            seg = segs[k]
            k += 1
            assert seg.kind == "dwell" and seg.duration == pytest.approx(wp.dwell_s, abs=1e-12)
            expected += wp.dwell_s
        p, v, a = plan.sample(expected)
        assert np.allclose(p, wp.xz, rtol=0, atol=MIN_MOVE_M +
                           1e-14) and not v.any() and not a.any()
    assert k == len(plan.segments)
    assert plan.duration == pytest.approx(expected, rel=1e-12, abs=1e-12)
    dt = min(DT, lim.a_max / lim.j_max / 20)
    n = plan.duration / dt
    if n > 2e5:
        dt = plan.duration / 2e5
    check_limits(plan, lim, dt=dt)
    assert plan.max_speed <= lim.v_max * (1 + REL)


def test_autostart_refusal_and_approach_plan():
    """The planner node's start rules (planning.movement): autostart only at home or at
    the plan's start; from elsewhere an approach at the given limits comes first."""
    from rheo_shaping.params.cell import CellParams
    from rheo_shaping.planning.movement import approach_plan, autostart_refusal, movement_plan
    cell = CellParams()
    plan = movement_plan(cell).plan
    home, start = cell.tool.home, plan.start
    assert autostart_refusal(home, home, start, 1e-3) == ""
    assert autostart_refusal(np.asarray(start) + [5e-4, 0.0], home, start, 1e-3) == ""
    why = autostart_refusal((0.5, 0.5), home, start, 1e-3)
    assert "neither at home nor at the plan's start" in why and "(0.5000, 0.5000)" in why
    assert approach_plan(cell, plan, None, DEFAULT_LIMITS) is plan
    assert approach_plan(cell, plan, start, DEFAULT_LIMITS) is plan
    away = np.asarray(start) + [0.0, 0.01]
    ap = approach_plan(cell, plan, away, DEFAULT_LIMITS)
    assert ap.start == pytest.approx(away)
    assert ap.segments[0].label == "approach"
    assert ap.duration > plan.duration
    p_end = ap.sample(ap.duration)[0]
    assert p_end == pytest.approx(plan.sample(plan.duration)[0], abs=1e-9)


def test_abort_from_the_executed_time_behind_the_newest_set_point():
    """The planner stops from where the tool is (/tool/pose), which trails the set-points it
    sent by up to max_lead: the stop starts from the plan's exact state at that time."""
    from rheo_shaping.params.cell import CellParams
    from rheo_shaping.planning.movement import movement_plan
    from rheo_shaping.planning.stopping import TrajectoryStreamer, stop_from_state
    plan = movement_plan(CellParams()).plan
    s = TrajectoryStreamer()
    s.start(plan, 0.0)
    s.setpoint(20.5)                          # sent ahead ...
    s.abort(20.0, "tension")                  # ... of the executed pose at 20 s
    assert s.abort_time == 20.0
    expect = stop_from_state(*plan.sample(20.0), plan.limits)
    assert s.stop_plan.duration == pytest.approx(expect.duration, abs=1e-12)
    assert np.allclose(s.setpoint(20.0)[0], plan.sample(20.0)[0], atol=1e-12)
    assert np.allclose(s.setpoint(20.2)[0], expect.sample(0.2)[0], atol=1e-12)
