//! Behaviour versions: the one list of them. Everything else that names versions (the registered
//! ids, the PettingZoo modules, every manual's Version History, the documentation's tables, the
//! tests' version lists) is derived from [`VERSIONS`] through `_core.versions()`.
//!
//! A version is an entry here: what it changed and why in one line, and the defaults it replaced
//! (the keys it changed, with the previous version's values). The latest version's defaults are
//! those the modules declare; an earlier version's are those, then the `before` overlays of
//! every later version applied newest first ([`overlays_down_to`]), so that a key changed twice
//! takes the oldest value. Adding a version: change the defaults in their modules, add an entry
//! whose `before` holds the old values, record the new version's golden digests.

/// One behaviour version.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Version {
    /// Its number: the `-vN` of the ids.
    pub number: u32,
    /// A few words on what it is ("The real robot's dynamics").
    pub title: &'static str,
    /// What changed from the version before and why, in a sentence or two: every manual's
    /// Version History line (docs/dynamics.md has the long story).
    pub summary: &'static str,
    /// The previous version's values of the keys this version changed, as TOML (empty for the
    /// first version).
    pub before: &'static str,
}

/// Every behaviour version, oldest first, numbered 0, 1, 2, ... without gaps.
pub const VERSIONS: &[Version] = &[
    Version {
        number: 0,
        title: "The paper's V-REP dynamics",
        summary: "The KH4VREP paper's V-REP-like dynamics: the body's velocity is imposed \
                  (kinematic drive), contacts are frictionless, the wheels reach their command \
                  within a step, the sonars refresh every step and echo from any angle.",
        before: "",
    },
    Version {
        number: 1,
        title: "The real robot's dynamics",
        summary: "Tyres with bounded grip drive the body, contacts have friction (0.7), the \
                  wheels ramp at K-Team's default profile rate (0.203 m/s²), the robot carries a \
                  gyroscope, the sonars refresh every 100 ms and do not echo beyond 22.5° from a \
                  surface's normal: pushed into a wall a robot slows, turns and stalls.",
        before: r#"
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
    },
    Version {
        number: 2,
        title: "One robot in the simulator and on the bench",
        summary: "The wheels follow K-Team's speed profile as the firmware computes it, at \
                  Acc_Inc 40 (2.71 m/s²), which the program `khepera-gym export` writes sets on \
                  the robot; v1's 0.203 m/s² ramp was not what that program set. Contacts \
                  changed with it: robots roll substep by substep, each one's path its own, not \
                  one arc over the step (`physics.whole_step_arc`); a contact is made at 1.25 x \
                  what two robots at full speed close in a substep, not rapier's 0.02 m, so \
                  head-on impacts meet it before the robots overlap \
                  (`physics.contact_prediction`); a slipping robot with nothing to touch moves \
                  by its tyres' impulses, not rapier's step of the world \
                  (`physics.slip_solver`).",
        before: r#"
[motors]
mode = "ramp"                # v1: the wheels ramp at robot.wheel_accel_limit (0.203 m/s^2, K-Team's default profile rate) without the profile's minimum speed

[physics]
whole_step_arc = true        # v1: split = "robot" worlds rolled one arc over the whole step when nothing could be touched
contact_prediction = 0.02    # v1: rapier's default, whatever the speeds
slip_solver = "rapier"       # v1: a slipping robot's world went to rapier even with nothing to touch
"#,
    },
    Version {
        number: 3,
        title: "Contacts with the scene solved as a rigid disc's",
        summary: "A robot's contacts with walls and obstacles are solved directly, as a rigid \
                  disc's with Coulomb friction, instead of by rapier's step of the whole world: \
                  the same contact model at a fraction of the cost; contacts between robots stay \
                  with rapier.",
        before: r#"
[physics]
scene_solver = "rapier"      # v2 and earlier: a robot's contacts with walls and obstacles went to rapier's step of the whole world
"#,
    },
];

/// The behaviour version of the current defaults: the last entry of [`VERSIONS`].
pub const LATEST_VERSION: u32 = VERSIONS[VERSIONS.len() - 1].number;

// The numbers are 0, 1, 2, ... in order: a version's position is its number.
const _: () = {
    let mut i = 0;
    while i < VERSIONS.len() {
        assert!(
            VERSIONS[i].number as usize == i,
            "VERSIONS must be numbered 0, 1, 2, ..."
        );
        i += 1;
    }
};

/// The `before` overlays that turn the latest defaults into version `version`'s, in the order
/// they apply: newest first, down to the version after `version` (an older overlay then wins
/// over a newer one on a key both change). Empty for the latest version.
pub fn overlays_down_to(versions: &[Version], version: u32) -> impl Iterator<Item = &Version> {
    versions.iter().rev().filter(move |v| v.number > version)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(number: u32, before: &'static str) -> Version {
        Version {
            number,
            title: "",
            summary: "",
            before,
        }
    }

    #[test]
    fn overlays_apply_newest_first_so_the_oldest_value_of_a_key_wins() {
        // x changed in v1 (from 0) and again in v3 (from 1): v0 has 0, v1 and v2 have 1.
        let versions = [
            entry(0, ""),
            entry(1, "x = 0"),
            entry(2, "y = 1"),
            entry(3, "x = 1"),
        ];
        let value_of_x = |version: u32| {
            let mut table = toml::Table::new();
            table.insert("x".into(), toml::Value::Integer(2));
            for v in overlays_down_to(&versions, version) {
                let overlay: toml::Table = v.before.parse().expect("test overlay");
                for (key, value) in overlay {
                    table.insert(key, value);
                }
            }
            table["x"].as_integer().expect("x")
        };
        assert_eq!(value_of_x(3), 2);
        assert_eq!(value_of_x(2), 1);
        assert_eq!(value_of_x(1), 1);
        assert_eq!(value_of_x(0), 0);
        let order: Vec<u32> = overlays_down_to(&versions, 0).map(|v| v.number).collect();
        assert_eq!(order, [3, 2, 1]);
        assert_eq!(overlays_down_to(&versions, 3).count(), 0);
    }

    #[test]
    fn every_version_says_what_it_changed_and_every_later_one_what_it_replaced() {
        assert_eq!(LATEST_VERSION as usize, VERSIONS.len() - 1);
        for v in VERSIONS {
            assert!(
                !v.title.is_empty() && !v.summary.is_empty(),
                "v{}",
                v.number
            );
            assert!(!v.summary.contains('\n'), "v{}: one line", v.number);
            let overlay: toml::Table = v.before.parse().expect("a version's overlay is TOML");
            assert_eq!(overlay.is_empty(), v.number == 0, "v{}", v.number);
        }
    }
}
