"""The benchmark peers of issue 54 (benchmarks/peers/) against the Khepera IV's real numbers.

These are external checks of the peers, not of khepera_gym: the expected values are the robot's
numbers as the K-Team manual gives them (docs/robot.md, the dossier written from the manual),
written out here rather than imported from the code under test, and nothing of khepera_gym is
used (but the last test, of the results page's section). They
keep the side-by-side benchmark honest: the NumPy and VMAS envs simulate the robot that the
Rust core does (speed limit, axle, sensor range), so their throughput is that of the same job.
No timing here (the comparison is a benchmark, ``python -m benchmarks.peers.compare_peers``).
The VMAS tests skip where VMAS is not installed (it is a benchmark-only dependency, not in CI).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.peers.numpy_khepera import NumpyKheperaNav

#: Closed-loop wheel speed limit (m/s): about 1200 units of 0.678 mm/s, robot.md §1 [C].
MANUAL_MAX_WHEEL_SPEED = 0.813
#: Wheel separation (m): KH4_WHEELS_DISTANCE 105.4 mm, robot.md §1 [C].
MANUAL_AXLE = 0.1054
#: Body radius (m): 140.8 mm diameter, robot.md §1 [C].
MANUAL_RADIUS = 0.0704
#: Infrared range beyond the shell (m): 2-250 mm, robot.md §2 [C].
MANUAL_IR_RANGE = 0.25
#: Control step of the scene (s): Nav's 50 ms.
STEP = 0.05
#: The ring's bearings in K-Team's order (back-left first), robot.md §2.
FRONT, LEFT, BACK = 3, 1, 7


def lone_robot(x: float = 0.0, y: float = 0.0, heading: float = 0.0) -> NumpyKheperaNav:
    """One world with its obstacles moved far outside the arena, the robot placed as given and
    the goal in a corner it will not reach."""
    env = NumpyKheperaNav(1, seed=0)
    env.reset(seed=0)
    env.obstacle_x[:] = 100.0
    env.obstacle_y[:] = 100.0
    env.x[:], env.y[:], env.heading[:] = x, y, heading
    env.goal_x[:], env.goal_y[:] = -0.9, -0.9
    return env


def place_obstacle(env: NumpyKheperaNav, x: float, y: float, radius: float) -> None:
    env.obstacle_x[0], env.obstacle_y[0], env.obstacle_radius[0] = x, y, radius


def test_full_forward_command_moves_at_the_manuals_top_speed() -> None:
    env = lone_robot()
    env.step(np.array([[1.0, 1.0]], np.float32))
    assert env.x[0] / STEP == pytest.approx(MANUAL_MAX_WHEEL_SPEED, rel=1e-5)
    assert env.y[0] == pytest.approx(0.0, abs=1e-7)
    assert env.heading[0] == pytest.approx(0.0, abs=1e-7)


def test_commands_beyond_full_scale_are_held_at_the_speed_limit() -> None:
    env = lone_robot()
    env.step(np.array([[3.0, 3.0]], np.float32))
    assert env.x[0] / STEP == pytest.approx(MANUAL_MAX_WHEEL_SPEED, rel=1e-5)


def test_spinning_in_place_turns_at_twice_the_wheel_speed_over_the_axle() -> None:
    env = lone_robot()
    env.step(np.array([[-1.0, 1.0]], np.float32))  # left back, right forward: counter-clockwise
    yaw_rate = 2.0 * MANUAL_MAX_WHEEL_SPEED / MANUAL_AXLE  # 15.4 rad/s, robot.md §1 [D]
    assert env.heading[0] / STEP == pytest.approx(yaw_rate, rel=1e-5)
    assert (env.x[0], env.y[0]) == pytest.approx((0.0, 0.0), abs=1e-6)


def test_unequal_wheels_follow_the_circle_their_speeds_and_the_axle_define() -> None:
    left, right = 0.5 * MANUAL_MAX_WHEEL_SPEED, MANUAL_MAX_WHEEL_SPEED
    # Turning radius of a differential drive about the instantaneous centre (0, R).
    radius = MANUAL_AXLE / 2 * (right + left) / (right - left)
    env = lone_robot()
    for _ in range(4):
        env.step(np.array([[0.5, 1.0]], np.float32))
    assert math.hypot(env.x[0], env.y[0] - radius) == pytest.approx(radius, rel=1e-5)
    travelled = 4 * STEP * (left + right) / 2
    assert env.heading[0] == pytest.approx(travelled / radius, rel=1e-5)


def test_rays_read_their_full_range_when_nothing_is_near() -> None:
    env = lone_robot()
    env.step(np.zeros((1, 2), np.float32))
    np.testing.assert_allclose(env.rays[:, 0], MANUAL_RADIUS + MANUAL_IR_RANGE, rtol=1e-6)


@pytest.mark.parametrize(
    ("ray", "centre"), [(FRONT, (0.25, 0.0)), (LEFT, (0.0, 0.25)), (BACK, (-0.25, 0.0))]
)
def test_a_ray_reads_the_distance_to_an_obstacle_on_its_bearing(
    ray: int, centre: tuple[float, float]
) -> None:
    env = lone_robot()
    place_obstacle(env, *centre, radius=0.05)
    env.step(np.zeros((1, 2), np.float32))
    assert env.rays[ray, 0] == pytest.approx(0.25 - 0.05, rel=1e-5)
    others = np.delete(env.rays[:, 0], ray)
    # Only the ray on the obstacle's bearing meets it (its neighbours pass 45° off).
    np.testing.assert_allclose(others, MANUAL_RADIUS + MANUAL_IR_RANGE, rtol=1e-6)


def test_the_ray_ring_turns_with_the_robot() -> None:
    env = lone_robot(heading=math.pi / 2)  # facing +y: the front ray points along +y
    place_obstacle(env, 0.0, 0.25, radius=0.05)
    env.step(np.zeros((1, 2), np.float32))
    assert env.rays[FRONT, 0] == pytest.approx(0.2, rel=1e-5)


def test_a_ray_reads_the_distance_to_a_wall() -> None:
    env = lone_robot(x=0.8)  # the wall's inner face is at x = 1 m
    env.step(np.zeros((1, 2), np.float32))
    assert env.rays[FRONT, 0] == pytest.approx(0.2, rel=1e-5)
    # 45° off the wall's normal the same wall is 0.2 / cos 45° away.
    assert env.rays[FRONT - 1, 0] == pytest.approx(0.2 * math.sqrt(2), rel=1e-5)


def test_walls_stop_the_robot_at_its_radius_and_count_as_contact() -> None:
    env = lone_robot(x=0.8)
    for _ in range(10):
        env.step(np.array([[1.0, 1.0]], np.float32))
    assert env.x[0] == pytest.approx(1.0 - MANUAL_RADIUS, abs=1e-6)
    assert env.in_contact[0]


def test_obstacles_are_solid_to_the_robots_disc() -> None:
    env = lone_robot()
    place_obstacle(env, 0.3, 0.0, radius=0.05)
    for _ in range(10):
        env.step(np.array([[1.0, 1.0]], np.float32))
    gap = math.hypot(env.x[0] - 0.3, env.y[0]) - 0.05 - MANUAL_RADIUS
    assert gap == pytest.approx(0.0, abs=1e-6)
    assert env.in_contact[0]


def test_resets_place_robot_and_goal_clear_of_obstacles_and_walls() -> None:
    env = NumpyKheperaNav(512, seed=3)
    env.reset(seed=3)
    inner = 1.0 - MANUAL_RADIUS
    assert np.all(np.abs(env.x) <= inner) and np.all(np.abs(env.y) <= inner)
    clearance = np.hypot(env.x - env.obstacle_x, env.y - env.obstacle_y) - env.obstacle_radius
    assert np.mean(np.all(clearance >= MANUAL_RADIUS, axis=0)) > 0.99
    assert np.all(np.abs(env.obstacle_x) + env.obstacle_radius <= 1.0)


def test_a_truncated_world_resets_on_the_next_step_with_reward_zero() -> None:
    env = NumpyKheperaNav(2, seed=0)
    env.reset(seed=0)
    still = np.zeros((2, 2), np.float32)
    for _ in range(399):
        _, _, terminated, truncated, _ = env.step(still)
        assert not truncated.any() and not terminated.any()
    _, _, _, truncated, _ = env.step(still)
    assert truncated.all()
    _, rewards, _, truncated, _ = env.step(still)
    assert not truncated.any()
    np.testing.assert_array_equal(rewards, 0.0)
    np.testing.assert_array_equal(env.steps, 0)


# --- VMAS (optional) ---------------------------------------------------------------------------
def vmas_lone_robot(heading: float = 0.0) -> Any:
    """The VMAS scenario's one world (a vmas ``Environment``) with its obstacles moved far
    away and the robot at the origin."""
    pytest.importorskip("vmas", reason="VMAS is a benchmark-only dependency (README.md)")
    import torch
    import vmas

    from benchmarks.peers.vmas_khepera import Scenario

    env = vmas.make_env(Scenario(), num_envs=1, device="cpu", continuous_actions=True, seed=0)
    env.reset()
    scenario = env.scenario
    for index, obstacle in enumerate(scenario.obstacles):
        obstacle.set_pos(torch.tensor([50.0 + index, 50.0]), batch_index=0)
    scenario.goal.set_pos(torch.tensor([-0.9, -0.9]), batch_index=0)
    scenario.robot.set_pos(torch.tensor([0.0, 0.0]), batch_index=0)
    scenario.robot.set_rot(torch.tensor([heading]), batch_index=0)
    return env


def test_vmas_robot_moves_at_the_manuals_top_speed_once_under_way() -> None:
    env = vmas_lone_robot()
    import torch

    full = torch.ones(1, 2)
    env.step([full])  # VMAS' drive reaches the commanded speed within its first step
    before = env.scenario.robot.state.pos.clone()
    env.step([full])
    speed = float(torch.linalg.vector_norm(env.scenario.robot.state.pos - before)) / STEP
    assert speed == pytest.approx(MANUAL_MAX_WHEEL_SPEED, rel=1e-3)


def test_vmas_robot_spins_at_twice_the_wheel_speed_over_the_axle() -> None:
    env = vmas_lone_robot()
    import torch

    spin = torch.tensor([[-1.0, 1.0]])
    env.step([spin])
    before = float(env.scenario.robot.state.rot)
    env.step([spin])
    yaw_rate = (float(env.scenario.robot.state.rot) - before) / STEP
    assert yaw_rate == pytest.approx(2.0 * MANUAL_MAX_WHEEL_SPEED / MANUAL_AXLE, rel=1e-3)


def test_vmas_lidar_reads_the_distance_to_an_obstacle_and_its_range_elsewhere() -> None:
    env = vmas_lone_robot()
    import torch

    scenario = env.scenario
    radius = scenario.obstacles[0].shape.radius
    scenario.obstacles[0].set_pos(torch.tensor([0.25 + radius, 0.0]), batch_index=0)
    rays = scenario.robot.sensors[0].measure()[0]
    assert float(rays[FRONT]) == pytest.approx(0.25, rel=1e-4)
    others = np.delete(rays.numpy(), FRONT)
    np.testing.assert_allclose(others, MANUAL_RADIUS + MANUAL_IR_RANGE, rtol=1e-5)


# --- the results page's section ----------------------------------------------------------------
def test_results_page_shows_the_ratios_beside_the_cpus_vector_extensions() -> None:
    from khepera_gym.analysis.docgen.peers import peers_section

    def row(peer: str, label: str, num_envs: int, threads: int, rounds: list[float]) -> dict:
        spread = {"median": float(np.median(rounds)), "min": min(rounds), "max": max(rounds)}
        key = f"{label} n={num_envs} t={threads}"
        return {
            "peer": peer,
            "label": label,
            "num_envs": num_envs,
            "threads": threads,
            "key": key,
            "rounds": rounds,
            "env_steps_per_second": spread,
        }

    rows = [
        row("khepera_gym", "khepera_gym Nav-v3", 1024, 2, [2.0e6, 2.2e6]),
        row("vmas", "VMAS", 4096, 1, [1.0e5, 1.0e5]),
        row("numpy", "NumPy", 4096, 1, [4.0e5, 5.0e5]),
    ]
    document = {
        "cpu_flags": {"avx2": True, "fma": True, "avx512f": True, "avx512_fp16": False},
        "settings": {"repetitions": 2, "duration_seconds": 4.0},
        "rows": rows,
        "ratios": [
            {"row": rows[0]["key"], "over": rows[1]["key"], "peer": "vmas"}
            | {"median": 21.0, "min": 20.0, "max": 22.0},
            {"row": rows[0]["key"], "over": rows[2]["key"], "peer": "numpy"}
            | {"median": 4.7, "min": 4.4, "max": 5.0},
        ],
    }
    text = peers_section(document)
    assert "AVX2, FMA, AVX-512F (not FP16)" in text
    assert "| Nav-v3 | 2 | 21.0× (20.0–22.0) | 4.7× (4.4–5.0) |" in text
    assert "| VMAS | scene | 4,096 | 1 | 100.0k | 100.0k–100.0k |" in text
