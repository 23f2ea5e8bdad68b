//! The layers `src/lib.rs` describes are the ones the code has. Its doc comment lists the
//! crate's top-level modules as bullets, lowest layer first; a module may use only modules of
//! the bullets above its own. Every path into another top-level module counts (`crate::world`,
//! `$crate::sensors` in a macro, `super::super::world` out of a nested file, a name lib.rs
//! re-exports such as `crate::Scenario`), in code, not in comments; test modules (`tests.rs`
//! files, and a file's `#[cfg(test)] mod ... {` at its end) may use anything.

use std::path::{Path, PathBuf};

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// The modules lib.rs declares (`mod name;` or `pub mod name;`).
fn declared(lib: &str) -> Vec<String> {
    lib.lines()
        .filter_map(|line| {
            let line = line.trim();
            let line = line.strip_prefix("pub ").unwrap_or(line);
            Some(line.strip_prefix("mod ")?.strip_suffix(';')?.to_owned())
        })
        .collect()
}

/// The layers of lib.rs's doc comment, lowest first: on each `//! * ` bullet (and the lines that
/// continue it), the names in backquotes that are declared modules.
fn layers(lib: &str, declared: &[String]) -> Vec<Vec<String>> {
    let mut layers: Vec<Vec<String>> = Vec::new();
    for line in lib.lines() {
        let Some(doc) = line.strip_prefix("//!") else {
            continue;
        };
        let text = if let Some(bullet) = doc.strip_prefix(" * ") {
            layers.push(Vec::new());
            bullet
        } else if doc.starts_with("   ") && !layers.is_empty() {
            doc
        } else {
            continue;
        };
        let layer = layers.last_mut().expect("a bullet was opened");
        // Between backquotes: the odd pieces of a split on them.
        for name in text.split('`').skip(1).step_by(2) {
            if declared.iter().any(|module| module == name) {
                layer.push(name.to_owned());
            }
        }
    }
    layers
}

/// Names lib.rs re-exports (`pub use module::{A, B};`), with the module each comes from.
fn reexports(lib: &str) -> Vec<(String, String)> {
    let mut names = Vec::new();
    for line in lib.lines() {
        let Some(path) = line.trim().strip_prefix("pub use ") else {
            continue;
        };
        let Some((module, items)) = path.trim_end_matches(';').split_once("::") else {
            continue;
        };
        for item in items.trim_matches(|c| c == '{' || c == '}').split(',') {
            let item = item.trim();
            let name = item.rsplit("::").next().unwrap_or(item);
            names.push((name.to_owned(), module.to_owned()));
        }
    }
    names
}

/// The `.rs` files of a top-level module, with their module path (`["world", "layout"]`).
fn files_of(module: &str) -> Vec<(PathBuf, Vec<String>)> {
    let mut files = Vec::new();
    let single = src().join(format!("{module}.rs"));
    if single.exists() {
        files.push((single, vec![module.to_owned()]));
    }
    let mut dirs = vec![(src().join(module), vec![module.to_owned()])];
    while let Some((dir, path)) = dirs.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for entry in entries {
            let file = entry.expect("a directory entry").path();
            let stem = file.file_stem().and_then(|s| s.to_str()).unwrap_or("");
            let mut inner = path.clone();
            if file.is_dir() {
                inner.push(stem.to_owned());
                dirs.push((file, inner));
            } else if file.extension().is_some_and(|ext| ext == "rs") {
                if stem != "mod" {
                    inner.push(stem.to_owned());
                }
                files.push((file, inner));
            }
        }
    }
    files
}

/// The code of a file that is not a test: none for a `tests.rs` file or one under a `tests`
/// folder; else the file up to its test module, each line without its comment.
fn code_of(file: &Path, module_path: &[String]) -> Vec<String> {
    if module_path.iter().any(|part| part == "tests") {
        return Vec::new();
    }
    let text = std::fs::read_to_string(file).expect("a readable source file");
    let lines: Vec<&str> = text.lines().collect();
    let end = (0..lines.len())
        .find(|&i| {
            lines[i].trim() == "#[cfg(test)]"
                && lines.get(i + 1).is_some_and(|next| {
                    let next = next.trim();
                    next.starts_with("mod ") && next.ends_with('{')
                })
        })
        .unwrap_or(lines.len());
    lines[..end]
        .iter()
        .map(|line| line.split("//").next().unwrap_or("").to_owned())
        .collect()
}

/// The top-level items a line names through the crate's root: `crate::x` (`$crate::x` too),
/// and `super::`…`::x` with as many `super`s as the file is deep.
fn root_paths(line: &str, depth: usize) -> Vec<String> {
    let word = |c: char| c.is_ascii_alphanumeric() || c == '_';
    let first_name = |rest: &str| rest.split(|c: char| !word(c)).next().unwrap_or("").to_owned();
    let mut found = Vec::new();
    for (at, _) in line.match_indices("crate::") {
        if !line[..at].ends_with(word) {
            found.push(first_name(&line[at + "crate::".len()..]));
        }
    }
    for (at, _) in line.match_indices("super::") {
        if line[..at].ends_with(word) || line[..at].ends_with("super::") {
            continue; // not the first `super` of a chain
        }
        let mut rest = &line[at..];
        let mut ups = 0;
        while let Some(after) = rest.strip_prefix("super::") {
            rest = after;
            ups += 1;
        }
        if ups >= depth {
            found.push(first_name(rest));
        }
    }
    found
}

#[test]
fn every_module_uses_only_the_layers_below_it_in_lib_rs() {
    let lib = std::fs::read_to_string(src().join("lib.rs")).expect("src/lib.rs");
    let declared = declared(&lib);
    let layers = layers(&lib, &declared);
    let mut listed: Vec<&String> = layers.iter().flatten().collect();
    listed.sort();
    let mut all: Vec<&String> = declared.iter().collect();
    all.sort();
    assert_eq!(
        listed, all,
        "lib.rs's layer list must name every module it declares, once"
    );
    let layer_of = |name: &str| layers.iter().position(|l| l.iter().any(|m| m == name));
    let reexports = reexports(&lib);
    let mut wrong = Vec::new();
    for (layer, modules) in layers.iter().enumerate() {
        for module in modules {
            let files = files_of(module);
            assert!(!files.is_empty(), "no source file for module {module}");
            for (file, module_path) in files {
                for (n, line) in code_of(&file, &module_path).iter().enumerate() {
                    for name in root_paths(line, module_path.len()) {
                        let used = reexports
                            .iter()
                            .find(|(reexported, _)| *reexported == name)
                            .map_or(name.as_str(), |(_, from)| from.as_str());
                        let Some(used_layer) = layer_of(used) else {
                            continue; // a macro or item of the root itself
                        };
                        if used != module && used_layer >= layer {
                            let file = file.strip_prefix(src()).unwrap_or(&file).display();
                            wrong.push(format!(
                                "src/{file}:{}: {module} (layer {}) uses {used} (layer {})",
                                n + 1,
                                layer + 1,
                                used_layer + 1
                            ));
                        }
                    }
                }
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "imports that break the layers of src/lib.rs (a module uses only the lines above its \
         own; move the shared code down, or change the layers there):\n{}",
        wrong.join("\n")
    );
}
