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
