//! VFH on hand-made readings: the twist in free space and near obstacles, the IR distance
//! inversion, the enlargement angle, blocked sectors and a kept turn.

use super::*;

#[test]
fn free_space_goes_straight_to_the_goal() {
    let vfh = Vfh::default();
    let (v, w) = vfh.twist(&[0.0; 8], &[1.0; 5], 1.0, 0.3, 0.0);
    assert!((w - 3.0 * 0.3f32.sin()).abs() < 1e-6);
    assert!(v > 0.0 && v < 0.3);
}

#[test]
fn sonar_too_close_with_a_clear_ir_ring_creeps_instead_of_stopping() {
    let vfh = Vfh::default();
    let us = [1.0, 1.0, 0.0, 1.0, 1.0]; // front: closer than the 25 cm minimum range
    let h = vfh.histogram(&[0.0; 8], &us);
    let ahead = h[vfh.sector(0.0)];
    // Saturated at the minimum range: 1 − 0.25/0.45, under h_m but over the threshold.
    assert!(
        (ahead - (1.0 - 0.25 / 0.45)).abs() < 1e-5,
        "density ahead {ahead}"
    );
    let (v, w) = vfh.twist(&[0.0; 8], &us, 1.0, 0.0, 0.0);
    assert!(v > 0.0 && v < 0.3 * vfh.vmax, "v = {v}");
    assert!(w.abs() > 0.1, "does not turn toward a side valley: {w}");
}

#[test]
fn sonar_too_close_and_ir_seeing_the_obstacle_stops() {
    let vfh = Vfh::default();
    let mut ir = [0.0; 8];
    ir[3] = 0.2; // front, about 7 cm
    let (v, _) = vfh.twist(&ir, &[1.0, 1.0, 0.0, 1.0, 1.0], 1.0, 0.0, 0.0);
    assert_eq!(v, 0.0);
}

#[test]
fn obstacle_ahead_slows_and_turns_to_a_free_sector() {
    let vfh = Vfh::default();
    let mut ir = [0.0; 8];
    ir[3] = 0.5; // front
    let us = [1.0, 1.0, 0.1, 1.0, 1.0]; // front echo at 0.2 m
    let (v, w) = vfh.twist(&ir, &us, 1.0, 0.0, 0.0);
    assert!(w.abs() > 0.1, "does not turn: {w}");
    assert!(v < 0.1, "does not slow: {v}");
}

#[test]
fn ir_distance_inverts_the_response_curve() {
    let vfh = Vfh::default();
    let ir = IrModel {
        range: 0.25,
        floor_value: 100.0,
        noise_sigma: 0.0,
        curve: CURVE_RAW,
    };
    for d in [0.005f32, 0.02, 0.05, 0.1, 0.15, 0.2] {
        let raw = ir.mean_raw(Some(d));
        let p = (raw - 100.0) / (IR_MAX_RAW - 100.0);
        let back = vfh.ir_distance(p).expect("seen");
        assert!(
            (back - d).abs() < 1e-3,
            "{d} m reads {p}, inverted to {back} m"
        );
    }
    assert_eq!(vfh.ir_distance(0.0), None);
}

#[test]
fn enlargement_is_asin_of_radius_plus_safety_over_distance() {
    let vfh = Vfh::default();
    let r = vfh.robot_radius;
    let rs = vfh.enlargement_radius;
    assert!((rs - (0.0704 + 0.015)).abs() < 1e-6);
    // An obstacle 0.3 m from the rim: γ = asin((r_r + d_s) / (r_r + 0.3)).
    let gamma = vfh.enlargement(0.3);
    assert!((gamma - (rs / (r + 0.3)).asin()).abs() < 1e-6);
    // Within the safety distance of the rim it blocks the whole half-plane toward it.
    assert_eq!(vfh.enlargement(0.01), 0.5 * PI);
}

#[test]
fn an_obstacle_at_the_shoulder_blocks_straight_ahead() {
    // The wall's end 1 cm off the front-left rim (p ≈ 0.95), nothing else seen: the path
    // straight ahead would graze it, so the enlarged histogram blocks it and the robot
    // turns right, away from it, even with the goal ahead and to the left.
    let vfh = Vfh::default();
    let mut ir = [0.0; 8];
    ir[2] = 0.95;
    let h = vfh.histogram(&ir, &[1.0; 5]);
    assert!(
        h[vfh.sector(0.0)] >= vfh.threshold,
        "ahead {}",
        h[vfh.sector(0.0)]
    );
    let (_, w) = vfh.twist(&ir, &[1.0; 5], 1.0, 0.2, 0.0);
    assert!(w < 0.0, "turns toward the obstacle: {w}");
}

#[test]
fn a_turn_toward_one_side_of_an_obstacle_is_kept() {
    // A wall straight ahead seen by the front sonar only: a valley wraps round the robot with
    // a way past on either side. The robot already turning right keeps to the right even
    // with the goal 15° to the left; at rest it takes the goal's side.
    let vfh = Vfh::default();
    let us = [1.0, 1.0, 0.15, 1.0, 1.0]; // an echo 30 cm ahead
    let goal = 15f32.to_radians();
    let (_, turning_right) = vfh.twist(&[0.0; 8], &us, 1.0, goal, -vfh.wmax);
    let (_, at_rest) = vfh.twist(&[0.0; 8], &us, 1.0, goal, 0.0);
    assert!(turning_right < 0.0, "switched sides: {turning_right}");
    assert!(at_rest > 0.0, "not the goal's side: {at_rest}");
}
