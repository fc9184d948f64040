"""Drive analysis: joint rates, constant-speed motor, motor choice, speed schedule, torque."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest

from paraloop_core import design, pipeline
from paraloop_core.algebra import dq, poly
from paraloop_core.linkage import drive, loops, schedule
from tests.independent.generic_designs import random_design

DESIGNS = Path(__file__).resolve().parents[1] / "assets" / "designs"
BUNDLED = sorted(p.stem for p in DESIGNS.glob("*.json"))  # the five bundled examples
RANDOM_SEEDS = (0, 3, 7, 25)  # best worst ratios 4.5 .. 2e6 (seed 3 has a very fast turn)


@functools.cache
def bundled(name: str) -> np.ndarray:
    sol = pipeline.solve(design.load_design(DESIGNS / f"{name}.json"), realize=False)
    return sol.loops[sol.design.loop].joint_factors


@functools.cache
def generic(seed: int) -> np.ndarray:
    sol = pipeline.solve(design.design_from_dict(random_design(seed)), realize=False)
    return sol.loops[sol.design.loop].joint_factors


def some_loops() -> list[np.ndarray]:
    return [bundled("tv8"), bundled("arc-sculpture")] \
        + [generic(s) for s in RANDOM_SEEDS]


def test_joint_rates_match_finite_differences_of_joint_angles():
    for jf in some_loops():
        a, b = jf[:, 0], np.linalg.norm(jf[:, 1:4], axis=1)
        t = np.concatenate([poly.cycle_parameters(a[:3], b[:3], 40),
                            (a[:, None] + b[:, None] * np.linspace(-3, 3, 13)).ravel(),
                            [-1e8, -1e3, 1e3, 1e8]])
        rate, accel = drive.joint_rates(jf, t)
        scale = np.hypot(t[:, None] - a, b)  # the Lorentzian's local width per joint
        for h_rel, check in ((1e-4, "rate"), (2e-3, "accel")):
            h = h_rel * scale
            tt = t[:, None] + np.array([-1.0, 0.0, 1.0])[:, None, None] * h  # (3, T, 6)
            phi = np.stack([loops.joint_angles(jf, tt[k].ravel()).reshape(len(t), 6, 6)
                            [:, np.arange(6), np.arange(6)] for k in range(3)])
            phi = np.unwrap(phi, axis=0)
            if check == "rate":
                fd = (phi[2] - phi[0]) / (2 * h)
                assert np.all(np.abs(fd - rate) * scale <= 1e-6)  # rate * scale <= 2
            else:
                fd = (phi[2] - 2 * phi[1] + phi[0]) / h**2
                assert np.all(np.abs(fd - accel) * scale**2 <= 1e-4)  # accel * scale^2 <= 2
    z_rate, z_acc = drive.joint_rates(some_loops()[0], np.array([np.inf, -np.inf]))
    assert not z_rate.any() and not z_acc.any()


def test_constant_speed_matches_time_integration():
    ct = 7.0
    omega = 2 * np.pi / ct
    for jf in some_loops()[:3] + [generic(25)]:  # (seed 3 turns too fast for float64 FD)
        a, b = jf[:, 0], np.linalg.norm(jf[:, 1:4], axis=1)
        t = np.unique(poly.cycle_parameters(a[:3], b[:3], 3000))  # clustered at the roots
        t = t[np.append(True, np.diff(t) > 1e-9 * (1 + np.abs(t[1:])))]  # tv8: shared roots
        phi = np.unwrap(loops.joint_angles(jf, t), axis=0)
        for m in range(6):
            theta = loops.JOINT_SIGN[m] * phi[:, m] + 2 * np.pi  # motor turn since t = -inf
            time = theta / omega  # constant motor speed: time is proportional to its angle
            cs = drive.constant_speed(jf, m, ct, theta=theta)
            assert np.allclose(cs.t, t, rtol=1e-6, atol=1e-9)
            fd = np.gradient(phi, time, axis=0)
            scale = np.abs(cs.velocity).max(axis=0)
            assert np.all(np.abs(fd - cs.velocity)[5:-5] <= 2e-3 * scale)
            fd2 = np.gradient(cs.velocity, time, axis=0)
            acc = np.abs(fd2 - cs.acceleration)[5:-5]
            big = np.abs(cs.acceleration).max(axis=0)
            assert np.all(acc <= 2e-2 * big + 1e-6 * big.max())  # + rounding of close samples
            # the motor turns at omega; its own ratio is 1
            assert np.allclose(np.abs(cs.velocity[:, m]), omega, rtol=1e-12)
            assert cs.peak_speed_ratio[m] == pytest.approx(1.0, rel=1e-12)


def test_constant_speed_mean_speed_and_exact_peaks():
    ct = 3.0
    for jf in some_loops():
        peaks = drive.peak_speed_ratios(jf)
        for m in (0, 4):
            cs = drive.constant_speed(jf, m, ct)
            fine = drive.constant_speed(jf, m, ct, samples=4096)
            # every joint turns once per cycle: mean |v| = 2 pi / cycle time (trapezoid in time;
            # its error is 8 % at 256 samples for the fastest turn here, seed 3: ratio 1e7)
            th = np.append(fine.theta, 2 * np.pi)
            v = np.abs(np.vstack([fine.velocity, fine.velocity[:1]]))
            mean = ((v[1:] + v[:-1]) / 2 * np.diff(th / (2 * np.pi / ct))[:, None]).sum(0) / ct
            assert np.allclose(mean, 2 * np.pi / ct, rtol=1e-3)
            assert np.allclose(cs.peak_speed_ratio, peaks[m], rtol=1e-9)
            assert cs.peak_speed_ratio.max() == pytest.approx(
                np.abs(cs.velocity).max() / (2 * np.pi / ct), rel=1e-12)
            # refining the samples never raises the peaks, coarse samples already find them
            coarse = drive.constant_speed(jf, m, ct, samples=16)
            for other in (fine, coarse):
                assert np.allclose(other.peak_speed_ratio, cs.peak_speed_ratio, rtol=1e-3)
                assert np.allclose(other.peak_accel, cs.peak_accel, rtol=1e-3)
            # brute force: a dense scan uniform in the motor angle and in t near the roots
            theta = np.linspace(0, 2 * np.pi, 200001)[:-1]
            dense = drive.constant_speed(jf, m, ct, theta=theta)
            brute = np.abs(dense.velocity).max(0) / (2 * np.pi / ct)
            assert np.all(brute <= cs.peak_speed_ratio * (1 + 1e-9))
            # a joint twinned with the motor (same norm root) has g' = 0: rounding noise of
            # 1e-23 of the largest peak, so the slack is relative to that one
            assert np.all(np.abs(dense.acceleration).max(0)
                          <= cs.peak_accel * (1 + 1e-9) + 1e-12 * cs.peak_accel.max())


def test_recommend_motor_rule_and_penalty():
    for jf in some_loops():
        worst = drive.peak_speed_ratios(jf).max(axis=1)
        for rest in range(6):
            pref = ((rest - 1) % 6, rest)
            choice = drive.recommend_motor(jf, rest)
            assert choice.preferred == pref
            assert f"joint {choice.motor}" in choice.reason
            best_pref = min(worst[list(pref)])
            if best_pref <= drive.PREFER_FACTOR * (1 + 1e-9) * worst.min():  # ties: resting
                assert choice.motor in pref and worst[choice.motor] == best_pref
            else:
                assert worst[choice.motor] == worst.min()
            assert choice.worst_speed_ratio == worst[choice.motor]
            assert drive.recommend_motor(jf, rest, prefer_factor=1e9).motor in pref
        assert drive.smooth_drive_penalty(jf) == worst.min() >= 1.0
        assert drive.smooth_drive_penalty(jf, motor=2) == worst[2]
    batch = np.stack(some_loops())
    assert np.allclose(drive.smooth_drive_penalty(batch),
                       [drive.smooth_drive_penalty(j) for j in batch])


def check_schedule(jf: np.ndarray, s: schedule.SpeedSchedule, ratio: float, acc: float) -> None:
    """Limits, cycle time and continuity, re-derived from joint_rates (not from the gear code)."""
    m, ct = s.motor, s.cycle_time
    assert s.time[-1] == pytest.approx(ct, rel=1e-9) and np.all(np.diff(s.time) > 0)
    assert s.motor_speed.min() > 0 and s.motor_speed[0] == s.motor_speed[-1]
    rate, _ = drive.joint_rates(jf, s.t)
    with np.errstate(invalid="ignore"):  # 0 / 0 at home (t = inf): taken from the schedule
        gear = rate / np.abs(rate[:, m : m + 1])
    gear[np.isinf(s.t)] = s.velocity[np.isinf(s.t)] / s.motor_speed[np.isinf(s.t), None]
    v = gear * s.motor_speed[:, None]
    assert np.allclose(v, s.velocity, rtol=1e-9, atol=0)
    assert np.abs(v).max() <= ratio * 2 * np.pi / ct * (1 + 1e-9)
    mean_acc = np.diff(v, axis=0) / np.diff(s.time)[:, None]  # averages within steps
    assert np.abs(mean_acc).max() <= acc * (1 + 1e-6)
    assert np.abs(s.acceleration).max() <= acc * (1 + 1e-9)
    assert s.achieved_accel.max() <= acc * (1 + 1e-9)
    assert s.achieved_speed_ratio.max() <= ratio * (1 + 1e-9)
    dense = dense_accel(jf, s)  # inside the steps too, by finite differences of joint speeds
    assert dense.max() <= acc * (1 + 1e-5), dense.max() / acc


def dense_accel(jf: np.ndarray, s: schedule.SpeedSchedule, n: int = 64) -> np.ndarray:
    """Joint accelerations (6,) max over n points per step: omega^2 linear in the motor
    angle within a step, joint speeds from joint_rates, time integrated in closed form."""
    m, x = s.motor, s.motor_speed**2
    lam = np.linspace(0.0, 1.0, n)
    th = s.theta[:-1, None] + np.diff(s.theta)[:, None] * lam  # (K, n)
    xs = x[:-1, None] * (1 - lam) + x[1:, None] * lam
    # time since the step's start: integral of d theta / sqrt(x) with x linear in theta
    tau = 2 * np.diff(s.theta)[:, None] * lam / (np.sqrt(xs) + np.sqrt(x[:-1, None]))
    a, b = jf[:, 0], np.linalg.norm(jf[:, 1:4], axis=1)  # norm roots a +- i b of the factors
    with np.errstate(divide="ignore"):
        t = a[m] - b[m] / np.tan(0.5 * th)  # motor angle -> loop parameter (joint_angles)
    rate, _ = drive.joint_rates(jf, t.ravel())
    rate = rate.reshape(*t.shape, 6)
    with np.errstate(invalid="ignore"):  # 0 / 0 at home (t = inf): that step is skipped
        v = rate / np.abs(rate[..., m:m + 1]) * np.sqrt(xs)[..., None]
    # steps under 1e-6 rad (fast turns) are left to drive's own DENSE check: there the
    # motor angle -> t map loses the digits these finite differences need
    ok = np.isfinite(v).all(axis=(1, 2)) & (np.diff(s.theta) > 1e-6)
    acc = np.diff(v[ok], axis=1) / np.diff(tau[ok], axis=1)[..., None]
    return np.abs(acc).max(axis=(0, 1))


@pytest.mark.parametrize("name", BUNDLED)
def test_schedule_meets_limits_on_bundled_examples(name):
    assert len(BUNDLED) == 5
    jf, ct = bundled(name), 10.0
    m = drive.recommend_motor(jf, 0).motor
    cs = drive.constant_speed(jf, m, ct)
    worst = cs.peak_speed_ratio.max()
    ratio, acc = worst / 2, cs.peak_accel.max()
    try:
        s = schedule.speed_schedule(jf, m, ct, ratio, acc)
    except schedule.InfeasibleScheduleError as err:  # half the constant-speed ratio is too tight
        assert np.isinf(err.min_cycle_time) and ratio < err.min_speed_ratio < worst
        assert "must exceed" in str(err)
        ratio = 0.5 * (err.min_speed_ratio + worst)
        s = schedule.speed_schedule(jf, m, ct, ratio, acc)
    check_schedule(jf, s, ratio, acc)
    assert s.achieved_speed_ratio.max() < worst  # smoother than at constant speed
    assert s.fastest_cycle_time <= ct


def test_infeasible_schedule_names_a_working_cycle_time():
    for jf in (bundled("arc-sculpture"), generic(7)):
        m, ct = drive.recommend_motor(jf, 0).motor, 10.0
        cs = drive.constant_speed(jf, m, ct)
        ratio = 0.7 * cs.peak_speed_ratio.max()
        acc = cs.peak_accel.max() / (10 * cs.peak_speed_ratio.max()**2)  # too small for 10 s
        with pytest.raises(schedule.InfeasibleScheduleError, match="smallest cycle time") as info:
            schedule.speed_schedule(jf, m, ct, ratio, acc)
        err = info.value
        assert err.min_cycle_time > ct and f"{err.min_cycle_time:.9g}" in str(err)
        s = schedule.speed_schedule(jf, m, err.min_cycle_time, ratio, acc)
        check_schedule(jf, s, ratio, acc)
        with pytest.raises(schedule.InfeasibleScheduleError):  # and it is the smallest one
            schedule.speed_schedule(jf, m, err.min_cycle_time * (1 - 1e-5), ratio, acc)
        need = err.accel_needed  # the accel limit named for the requested cycle time works
        check_schedule(jf, schedule.speed_schedule(jf, m, ct, ratio, need), ratio, need)
        with pytest.raises(schedule.InfeasibleScheduleError):
            schedule.speed_schedule(jf, m, ct, ratio, need * (1 - 1e-5))


def potential(jf, t, mass, centers, g_base, rest=0):
    """U = -sum m_l g . c_l (J), link centres moved by the link poses relative to the resting
    link ``rest`` (its frame: gravity ``g_base`` is fixed there; independent of drive)."""
    poses = loops.link_poses(jf, t)
    rel = dq.mul(dq.conj(poses[:, rest:rest + 1]), poses)  # rest^-1 * link (homogeneous)
    c = dq.transform_points(rel, centers)
    return -np.einsum("l,tlk,k->t", mass, c, g_base)


def test_torque_is_virtual_work_of_gravity():
    rng = np.random.default_rng(5)
    for k, jf in enumerate(some_loops()):
        a, b = jf[:, 0], np.linalg.norm(jf[:, 1:4], axis=1)
        size = np.abs(jf[:, 5:]).max() / b.min() + 1.0
        mass = rng.uniform(0.1, 2.0, 6)
        centers = rng.normal(size=(6, 3)) * size
        rot = dq.from_pos_wxyz(rng.normal(size=3), rng.normal(size=4))
        grav = np.array([0.0, 0.0, -9.81])
        g_base = dq.rotation_matrix(rot).T @ grav
        for m in (0, 3):
            # torque = dU/dtheta: central differences in t over the motor's turn, which is
            # 2 atan2(2 h b, (a - t)^2 - h^2 + b^2) by the definition of its joint angle
            t = np.concatenate([poly.cycle_parameters(a[:3], b[:3], 20),
                                (a[:, None] + b[:, None] * np.array([-1.0, 0.0, 1.0])).ravel(),
                                [-1e4, 1e4]])
            h = 1e-4 * np.hypot(t[:, None] - a, b).min(axis=1)
            dth = 2 * np.arctan2(2 * h * b[m], (a[m] - t) ** 2 - h**2 + b[m] ** 2)
            fd = (potential(jf, t + h, mass, centers, g_base)
                  - potential(jf, t - h, mass, centers, g_base)) / dth
            theta = loops.JOINT_SIGN[m] * loops.joint_angles(jf, t)[:, m] + 2 * np.pi
            got = drive.motor_torque(jf, m, mass, centers, grav, dq.to_matrix(rot), theta=theta)
            assert np.allclose(got.torque, fd, rtol=1e-5, atol=1e-7 * got.peak_torque)
            rest = 2 + m  # another link held still: the others move relative to it
            fd_rest = (potential(jf, t + h, mass, centers, g_base, rest)
                       - potential(jf, t - h, mass, centers, g_base, rest)) / dth
            on_rest = drive.motor_torque(jf, m, mass, centers, grav, dq.to_matrix(rot),
                                         theta=theta, resting_link=rest)
            assert np.allclose(on_rest.torque, fd_rest, rtol=1e-5,
                               atol=1e-7 * on_rest.peak_torque)
            assert on_rest.moving_mass_kg == pytest.approx(mass.sum() - mass[rest])
            tq = drive.motor_torque(jf, m, mass, centers, grav, rot)  # adaptive samples
            assert tq.peak_torque == pytest.approx(np.abs(tq.torque).max())
            assert tq.peak_torque >= got.peak_torque * (1 - 1e-3)
            assert tq.moving_mass_kg == pytest.approx(mass[1:].sum())
            home = drive.motor_torque(jf, m, mass, centers, grav, rot,
                                      theta=np.array([0.0, 1e-7, 2 * np.pi - 1e-7])).torque
            assert np.allclose(home[1:], home[0], rtol=1e-5, atol=1e-7 * tq.peak_torque)
            if k != 3:  # conservative gravity: no net work over a cycle (periodic trapezoid;
                # uniform samples cannot resolve seed 3's turn of a 1e-7 motor angle)
                theta = np.linspace(0, 2 * np.pi, 20001)[:-1]
                work = drive.motor_torque(jf, m, mass, centers, grav, rot, theta=theta).torque
                assert abs(work.sum()) <= 1e-6 * np.abs(work).sum()
    # lengths in mm and the unit in metres give the same torque
    jf = bundled("tv8")
    ref = drive.motor_torque(jf, 1, np.ones(6), np.ones((6, 3)), samples=64)
    mm = drive.motor_torque(dq.scale_lengths(jf, 1000.0), 1, np.ones(6), np.ones((6, 3)),
                            samples=64, length_unit_m=1e-3)
    assert np.allclose(mm.torque, ref.torque, rtol=1e-9, atol=1e-12 * ref.peak_torque)


def test_bad_input_raises_value_error():
    jf = bundled("tv8")
    zero_axis = jf.copy()
    zero_axis[2, 1:4] = 0.0
    cases = [
        (lambda: drive.joint_rates(jf[:5], [0.0]), "shape"),
        (lambda: drive.joint_rates(zero_axis, [0.0]), "rotation axis"),
        (lambda: drive.joint_rates(jf, [np.nan]), "NaN"),
        (lambda: drive.constant_speed(jf, 6, 1.0), "motor"),
        (lambda: drive.constant_speed(jf, True, 1.0), "motor"),
        (lambda: drive.constant_speed(jf, 0, -1.0), "cycle_time"),
        (lambda: drive.constant_speed(jf, 0, 1.0, samples=3), "samples"),
        (lambda: drive.recommend_motor(jf, 7), "resting_link"),
        (lambda: drive.smooth_drive_penalty(jf, motor=-1), "motor"),
        (lambda: schedule.speed_schedule(jf, 0, 1.0, 0.0, 1.0), "max_speed_ratio"),
        (lambda: schedule.speed_schedule(jf, 0, 1.0, 2.0, np.inf), "max_accel"),
        (lambda: drive.motor_torque(jf, 0, np.ones(5), np.zeros((6, 3))), "masses_kg"),
        (lambda: drive.motor_torque(jf, 0, -np.ones(6), np.zeros((6, 3))), "masses_kg"),
        (lambda: drive.motor_torque(jf, 0, np.ones(6), np.zeros((6, 3)),
                                    T_world_base=2 * np.eye(4)), "rotation"),
        (lambda: drive.motor_torque(jf, 0, np.ones(6), np.zeros((6, 3)),
                                    T_world_base=np.eye(3)), "T_world_base"),
    ]
    for call, words in cases:
        with pytest.raises(ValueError, match=words):
            call()
    with pytest.raises(schedule.InfeasibleScheduleError, match="no cycle time works"):
        schedule.speed_schedule(jf, 1, 1.0, 1.0, 1.0)  # a ratio of 1 is impossible here
