//! Built-in scenes: scenario files overlaid on a task's defaults like a user's file, embedded so
//! an installed wheel has them.

/// The built-in scenes: (name, text).
pub const SCENES: &[(&str, &str)] = &[
    ("paper_fig6", include_str!("../../configs/paper_fig6.toml")),
    ("paper_fig7", include_str!("../../configs/paper_fig7.toml")),
    ("swarm", include_str!("../../configs/swarm.toml")),
];

/// The text of a built-in scene.
pub fn scene(name: &str) -> Option<&'static str> {
    SCENES.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}
