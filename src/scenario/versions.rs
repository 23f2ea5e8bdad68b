//! The defaults of earlier behaviour versions, as overlays on the latest's.

/// What an earlier behaviour version's defaults were, as an overlay on the next version's:
/// (version, TOML). Applied, newest first, down to the version asked for, after a task's own
/// defaults, so that `KheperaIV-*-v0` keeps the behaviour its published numbers came from.
pub const VERSION_DEFAULTS: &[(u32, &str)] = &[
    (
        2,
        r#"
[physics]
scene_solver = "rapier"      # v2 and earlier: a robot's contacts with walls and obstacles went to rapier's step of the whole world
"#,
    ),
    (
        1,
        r#"
[motors]
mode = "ramp"                # v1: the wheels ramp at robot.wheel_accel_limit (0.203 m/s^2, K-Team's default profile rate) without the profile's minimum speed

[physics]
whole_step_arc = true        # v1: split = "robot" worlds rolled one arc over the whole step when nothing could be touched
contact_prediction = 0.02    # v1: rapier's default, whatever the speeds
slip_solver = "rapier"       # v1: a slipping robot's world went to rapier even with nothing to touch
"#,
    ),
    (
        0,
        r#"
[robot]
wheel_accel_limit = inf      # v0: wheels reached any commanded speed within one step

[physics]
substeps = 4                 # v0: four 12.5 ms substeps
drive = "kinematic"          # v0: velocity imposed on the body, no tyre model
friction = 0.0               # v0: frictionless shell: robots slid along walls

[sensors]
carry = ["ir", "us"]         # v0: no gyroscope model (sensor_readings' gyro_z is exact)
us_period = 0.0              # v0: the sonars refreshed at every control step
us_acceptance = 1.5707963267948966 # v0: an echo from any incidence angle
"#,
    ),
];
