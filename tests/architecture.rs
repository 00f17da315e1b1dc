//! The house's layering, checked on the source: every `crate::` path in `src/` names a module of
//! a strictly lower layer (or the importing module itself). Layers, bottom up, as drawn in
//! docs/ARCHITECTURE.md:
//!
//! 0 `error`, `testdata`; 1 `color`, `work` (progress, cancel): the ground floor
//! 2 `mesh`
//! 3 `geometry`, `stats`, `correspondence`
//! 4 `hierarchy`; 5 `features`; 6 `meshmatch`
//! 7 systems: `synthesis`, `applications`, `demo`
//! 8 clients of the engine: `jobs`, `bench`; 9 `render`; 10 `app`; 11 `cli`, `main`, `lib`
//!
//! A new top-level module must be given a layer here, so the picture stays true.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const LAYERS: &[(&str, u32)] = &[
    ("error", 0),
    ("testdata", 0),
    ("color", 1),
    ("work", 1),
    ("mesh", 2),
    ("geometry", 3),
    ("stats", 3),
    ("correspondence", 3),
    ("hierarchy", 4),
    ("features", 5),
    ("meshmatch", 6),
    ("synthesis", 7),
    ("applications", 7),
    ("demo", 7),
    ("ground_truth", 7),
    ("jobs", 8),
    ("bench", 8),
    ("render", 9),
    ("app", 10),
    ("cli", 11),
    ("main", 11),
    ("lib", 11),
];

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The top-level modules a file names through `crate::` paths (comments stripped; braces
/// expanded one level: `crate::{a::x, b}` names `a` and `b`).
fn imports(text: &str) -> BTreeSet<String> {
    let code: String = text
        .lines()
        .map(|l| match l.find("//") {
            Some(i) => &l[..i],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n");
    let mut out = BTreeSet::new();
    let mut rest = code.as_str();
    while let Some(i) = rest.find("crate::") {
        let before_ok = i == 0 || {
            let c = rest.as_bytes()[i - 1];
            !(c.is_ascii_alphanumeric() || c == b'_' || c == b':')
        };
        rest = &rest[i + "crate::".len()..];
        if !before_ok {
            continue;
        }
        if let Some(inner) = rest.strip_prefix('{') {
            let end = inner.find('}').unwrap_or(inner.len());
            for item in inner[..end].split(',') {
                let name: String = item
                    .trim()
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() {
                    out.insert(name);
                }
            }
        } else {
            let name: String = rest
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            out.insert(name);
        }
    }
    out
}

#[test]
fn every_import_points_down_the_layers() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let layer: BTreeMap<&str, u32> = LAYERS.iter().copied().collect();
    let mut files = Vec::new();
    rust_files(&root, &mut files);
    assert!(files.len() > 20, "src/ not found at {}", root.display());
    let mut bad = Vec::new();
    for f in &files {
        let rel = f.strip_prefix(&root).unwrap();
        let first = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy();
        let module = first.trim_end_matches(".rs").to_string();
        let Some(&own) = layer.get(module.as_str()) else {
            bad.push(format!("{}: module '{module}' has no layer", rel.display()));
            continue;
        };
        let text = std::fs::read_to_string(f).unwrap();
        for m in imports(&text) {
            if m == module {
                continue;
            }
            match layer.get(m.as_str()) {
                None => bad.push(format!(
                    "{}: imports crate::{m}, which is no module with a layer (use its own path, \
                     not a re-export from lib.rs)",
                    rel.display()
                )),
                Some(&l) if l >= own => bad.push(format!(
                    "{}: layer {own} ({module}) imports layer {l} ({m})",
                    rel.display()
                )),
                _ => {}
            }
        }
    }
    assert!(
        bad.is_empty(),
        "imports against the layers:\n{}",
        bad.join("\n")
    );
}

#[test]
fn the_import_checker_sees_braces_and_paths() {
    let got = imports(
        "use crate::{mesh::TriMesh, work};\nlet x = crate::geometry::f(); // crate::app\nsuper::crate::no",
    );
    let want: BTreeSet<String> = ["geometry", "mesh", "work"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    assert_eq!(got, want);
}

/// Module path of a file under `src/` (`app/state/mod.rs` -> `app::state`, `lib.rs` -> root).
fn module_of(rel: &Path) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| {
            c.as_os_str()
                .to_string_lossy()
                .trim_end_matches(".rs")
                .to_string()
        })
        .collect();
    if parts
        .last()
        .is_some_and(|p| p == "mod" || p == "lib" || p == "main")
    {
        parts.pop();
    }
    parts
}

/// Every module path a file names through `crate::`, `super::` or `self::` (comments stripped;
/// braces expanded one level), as the raw segments after the prefix, resolved against `me`.
fn module_paths(text: &str, me: &[String]) -> Vec<Vec<String>> {
    let code: String = text
        .lines()
        .map(|l| match l.find("//") {
            Some(i) => &l[..i],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n");
    let segments = |s: &str| -> Vec<String> {
        let mut out = Vec::new();
        let mut rest = s;
        loop {
            let name: String = rest
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            if name.is_empty() {
                break;
            }
            rest = &rest[name.len()..];
            out.push(name);
            match rest.strip_prefix("::") {
                Some(r) => rest = r,
                None => break,
            }
        }
        out
    };
    let mut out = Vec::new();
    let bytes = code.as_bytes();
    let mut i = 0;
    while i < code.len() {
        if !code.is_char_boundary(i) {
            i += 1;
            continue;
        }
        let starts = |i: usize, p: &str| code[i..].starts_with(p);
        let boundary = i == 0 || {
            let c = bytes[i - 1];
            !(c.is_ascii_alphanumeric() || c == b'_' || c == b':')
        };
        if !(boundary && (starts(i, "crate::") || starts(i, "super::") || starts(i, "self::"))) {
            i += 1;
            continue;
        }
        // The base module and the rest of the path.
        let mut base: Vec<String> = if starts(i, "crate::") {
            i += "crate::".len();
            Vec::new()
        } else {
            me.to_vec()
        };
        if starts(i, "self::") {
            i += "self::".len();
        }
        while code[i..].starts_with("super::") {
            base.pop();
            i += "super::".len();
        }
        // The path's segments, then one level of braces if it goes on with `::{` (or starts
        // with `{`).
        let rest = &code[i..];
        let lead = segments(rest);
        let consumed: usize = lead.iter().map(|s| s.len() + 2).sum::<usize>();
        let after = if lead.is_empty() {
            Some(rest)
        } else {
            rest.get(consumed.saturating_sub(2)..)
                .and_then(|r| r.strip_prefix("::"))
        };
        let heads: Vec<Vec<String>> = match after.and_then(|r| r.strip_prefix('{')) {
            Some(inner) => {
                let end = inner.find('}').unwrap_or(inner.len());
                inner[..end]
                    .split(',')
                    .map(|s| {
                        let mut h = lead.clone();
                        h.extend(segments(s.trim()));
                        h
                    })
                    .collect()
            }
            None => vec![lead],
        };
        for h in heads {
            let mut p = base.clone();
            p.extend(h);
            out.push(p);
        }
    }
    out
}

#[test]
fn no_import_loops_inside_folders() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&root, &mut files);
    let mods: BTreeMap<Vec<String>, PathBuf> = files
        .iter()
        .map(|f| (module_of(f.strip_prefix(&root).unwrap()), f.clone()))
        .collect();
    // Edges between siblings: a reference from module A to module B counts as one from A's
    // ancestor to B's ancestor just below their common ancestor; a folder's own front door
    // (its mod.rs) and its ancestors are left out, as is a module's own inside.
    let mut edges: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = BTreeMap::new();
    for (me, f) in &mods {
        // Unit tests (at the end of a file) may reach anything.
        let text = std::fs::read_to_string(f).unwrap();
        let text = text.split("#[cfg(test)]").next().unwrap_or("");
        for path in module_paths(text, me) {
            // The longest prefix that is a module.
            let mut target = Vec::new();
            for s in &path {
                let mut t = target.clone();
                t.push(s.clone());
                if mods.contains_key(&t) {
                    target = t;
                } else {
                    break;
                }
            }
            let common = me.iter().zip(&target).take_while(|(a, b)| a == b).count();
            if common >= me.len() || common >= target.len() {
                continue;
            }
            let from = me[..=common].to_vec();
            let to = target[..=common].to_vec();
            edges.entry(from).or_default().insert(to);
        }
    }
    // A loop is an edge whose head reaches back to its tail.
    let reaches = |from: &Vec<String>, goal: &Vec<String>| {
        let mut seen = BTreeSet::new();
        let mut stack = vec![from.clone()];
        while let Some(m) = stack.pop() {
            if &m == goal {
                return true;
            }
            if seen.insert(m.clone()) {
                stack.extend(edges.get(&m).into_iter().flatten().cloned());
            }
        }
        false
    };
    let mut loops = Vec::new();
    for (a, outs) in &edges {
        for b in outs {
            if reaches(b, a) {
                loops.push(format!("{} -> {} (and back)", a.join("::"), b.join("::")));
            }
        }
    }
    assert!(loops.is_empty(), "import loops:\n{}", loops.join("\n"));
}

#[test]
fn the_loop_checker_resolves_super_and_self() {
    let me: Vec<String> = ["app", "weather"].iter().map(|s| s.to_string()).collect();
    let got = module_paths(
        "use super::systems::X;\nuse self::inner::Y;\nuse super::super::mesh::{a, b::C};\n// super::no",
        &me,
    );
    let want: Vec<Vec<String>> = vec![
        vec!["app", "systems", "X"],
        vec!["app", "weather", "inner", "Y"],
        vec!["mesh", "a"],
        vec!["mesh", "b", "C"],
    ]
    .into_iter()
    .map(|v| v.into_iter().map(String::from).collect())
    .collect();
    assert_eq!(got, want);
}
