//! The directions in which Kestrel's top-level modules may import each other (ARCHITECTURE.md,
//! "Layers"). Reads every library file under `src/` (`main.rs` and the files under `src/cli/`
//! are the binary, above everything) and finds each reference to another top-level module:
//! `crate::X`, `crate::{X, ..}` and `super::` chains that climb to the crate root, in code and
//! in its tests, not in comments or string literals. Fails, naming the file and line, on an import in a
//! [`FORBIDDEN`] direction and on any cycle between top-level modules. The forbidden imports
//! that remain until the restructuring gets to them are listed in [`EXCEPTIONS`] with their
//! count per file: a new one fails, and so does one removed without lowering the count.

mod source_scan;

use source_scan::{code_only, tok, tokens};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Imports that must not exist: a module, the modules it must not reach, and why.
const FORBIDDEN: &[(&str, &[&str], &str)] = &[
    ("mission", &["config"], "mission is handed its settings"),
    (
        "safety",
        &["config"],
        "the safety stage is handed its settings",
    ),
    ("host", &["sim"], "the simulator is one fleet among others"),
    ("api", &["mapping", "planning"], "the API asks the host"),
    (
        "exploration",
        &["behavior", "api"],
        "behaviors ask exploration, not back",
    ),
    ("fleet_bus", &["api"], "the bus feeds the host, not the API"),
    ("flightlog", &["host"], "the host writes the log"),
    ("core", &["host"], "the host ticks the core"),
    (
        "config",
        &["sim"],
        "the config names the simulator's settings in types",
    ),
    ("platform", &["control", "mapping"], "platforms speak types"),
    (
        "behavior",
        &["platform", "api"],
        "behaviors see the platform through the core",
    ),
    (
        "planning",
        &["behavior"],
        "behaviors ask planning, not back",
    ),
    ("mapping", &["planning"], "planning reads maps, not back"),
    ("sim", &["core", "behavior"], "the simulator is a platform"),
];

/// Forbidden imports kept for now, each with the number of references in its file. Temporary:
/// lower the count (or drop the line) when one goes.
const EXCEPTIONS: &[(&str, &str, usize)] = &[];

/// One reference to another top-level module.
#[derive(Debug)]
struct Reference {
    from: String,
    file: String,
    line: usize,
    to: String,
}

#[test]
fn no_forbidden_imports() {
    let mut forbidden = Vec::new();
    let mut excepted: BTreeMap<(String, String), usize> = BTreeMap::new();
    for r in all_references() {
        let Some((_, _, why)) = FORBIDDEN
            .iter()
            .find(|(from, to, _)| *from == r.from && to.contains(&r.to.as_str()))
        else {
            continue;
        };
        if EXCEPTIONS
            .iter()
            .any(|(f, to, _)| *f == r.file && *to == r.to)
        {
            *excepted.entry((r.file, r.to)).or_default() += 1;
        } else {
            let Reference {
                from,
                file,
                line,
                to,
            } = r;
            forbidden.push(format!("{file}:{line}: {from} -> {to} ({why})"));
        }
    }
    for (file, to, listed) in EXCEPTIONS {
        let found = excepted
            .get(&(file.to_string(), to.to_string()))
            .copied()
            .unwrap_or(0);
        if found != *listed {
            forbidden.push(format!(
                "{file}: {found} references to {to}, {listed} listed in EXCEPTIONS: update the count"
            ));
        }
    }
    assert!(
        forbidden.is_empty(),
        "forbidden imports (ARCHITECTURE.md, Layers):\n{}",
        forbidden.join("\n")
    );
}

/// Beyond the list, no two top-level modules reach each other, directly or through others: the
/// imports form layers.
#[test]
fn no_import_cycles() {
    // Each import direction with its first reference.
    let mut edges: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    for r in all_references() {
        edges
            .entry(r.from)
            .or_default()
            .entry(r.to)
            .or_insert(format!("{}:{}", r.file, r.line));
    }
    let mut finished = Vec::new();
    for start in edges.keys() {
        let mut path = Vec::new();
        if let Some(cycle) = cycle_from(start, &edges, &mut path, &mut finished) {
            panic!(
                "import cycle (ARCHITECTURE.md, Layers):\n{}",
                cycle.join("\n")
            );
        }
    }
}

/// Depth-first search from `at`; a cycle comes back as its steps, `a -> b (file:line)`.
fn cycle_from(
    at: &str,
    edges: &BTreeMap<String, BTreeMap<String, String>>,
    path: &mut Vec<String>,
    finished: &mut Vec<String>,
) -> Option<Vec<String>> {
    if finished.iter().any(|f| f == at) {
        return None;
    }
    if let Some(k) = path.iter().position(|p| p == at) {
        let mut ring = path[k..].to_vec();
        ring.push(at.to_string());
        return Some(
            ring.windows(2)
                .map(|w| format!("{} -> {} ({})", w[0], w[1], edges[&w[0]][&w[1]]))
                .collect(),
        );
    }
    path.push(at.to_string());
    for next in edges.get(at).into_iter().flat_map(|e| e.keys()) {
        if let Some(cycle) = cycle_from(next, edges, path, finished) {
            return Some(cycle);
        }
    }
    path.pop();
    finished.push(at.to_string());
    None
}

/// Every reference of the library's files to another top-level module.
fn all_references() -> Vec<Reference> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let modules = top_level_modules(&src);
    assert!(
        !modules.iter().any(|m| m == "cli"),
        "src/cli/ is the binary's; the library has no module `cli`"
    );
    for (from, to, _) in FORBIDDEN {
        for m in std::iter::once(from).chain(to.iter()) {
            assert!(modules.iter().any(|x| x == m), "no module `{m}` in lib.rs");
        }
    }
    let mut all = Vec::new();
    for (module, path) in library_files(&src) {
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path:?}: {e}"));
        let rel = format!("src/{}", path.strip_prefix(&src).unwrap_or(&path).display());
        all.extend(references(
            &module,
            &rel,
            &text,
            depth(&src, &path),
            &modules,
        ));
    }
    all
}

/// The `pub mod` / `mod` names of lib.rs.
fn top_level_modules(src: &Path) -> Vec<String> {
    let lib = std::fs::read_to_string(src.join("lib.rs")).unwrap_or_default();
    let modules: Vec<String> = lib
        .lines()
        .filter_map(|l| {
            let l = l.trim().strip_prefix("pub ").unwrap_or(l.trim());
            Some(
                l.strip_prefix("mod ")?
                    .trim_end_matches(';')
                    .trim()
                    .to_string(),
            )
        })
        .collect();
    assert!(modules.len() > 10, "lib.rs lists the modules: {modules:?}");
    modules
}

/// Every `.rs` file of the library with its top-level module.
fn library_files(src: &Path) -> Vec<(String, PathBuf)> {
    let mut files = Vec::new();
    let mut stack = vec![src.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let entries = std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{dir:?}: {e}"));
        for entry in entries.flatten() {
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                let rel = path.strip_prefix(src).unwrap_or(&path);
                let first = rel
                    .components()
                    .next()
                    .map(|c| {
                        c.as_os_str()
                            .to_string_lossy()
                            .trim_end_matches(".rs")
                            .to_string()
                    })
                    .unwrap_or_default();
                if !["lib", "main", "cli"].contains(&first.as_str()) {
                    files.push((first, path));
                }
            }
        }
    }
    files.sort();
    assert!(
        files.len() > 50,
        "the library's files are found: {}",
        files.len()
    );
    files
}

/// How many `super::` climb from the file's own module to the crate root.
fn depth(src: &Path, path: &Path) -> usize {
    let rel = path.strip_prefix(src).unwrap_or(path);
    let parts = rel.components().count();
    if rel.file_name().is_some_and(|n| n == "mod.rs") {
        parts - 1
    } else {
        parts
    }
}

/// The references of `file` (of top-level module `own`, `depth` modules below the crate root)
/// to the other top-level `modules`.
fn references(
    own: &str,
    file: &str,
    text: &str,
    depth: usize,
    modules: &[String],
) -> Vec<Reference> {
    let tokens = tokens(&code_only(text));
    let mut found = Vec::new();
    let mut push = |line: usize, name: &str| {
        if name != own && modules.iter().any(|m| m == name) {
            found.push(Reference {
                from: own.to_string(),
                file: file.to_string(),
                line,
                to: name.to_string(),
            });
        }
    };
    // Inline `mod x {` blocks open at these brace depths.
    let mut inline_mods: Vec<usize> = Vec::new();
    let mut braces = 0usize;
    let mut i = 0;
    while i < tokens.len() {
        let (t, line) = (&tokens[i].0, tokens[i].1);
        match t.as_str() {
            "{" => braces += 1,
            "}" => {
                braces = braces.saturating_sub(1);
                if inline_mods.last() == Some(&braces) {
                    inline_mods.pop();
                }
            }
            "mod" if tok(&tokens, i + 2) == "{" => inline_mods.push(braces),
            _ => {}
        }
        let after_path = i > 0 && tok(&tokens, i - 1) == "::";
        let root = if t == "crate" && !after_path {
            Some(i + 1)
        } else if t == "super" && !after_path {
            let mut j = i;
            let mut climbs = 0;
            while tok(&tokens, j) == "super" && tok(&tokens, j + 1) == "::" {
                climbs += 1;
                j += 2;
            }
            (climbs >= depth + inline_mods.len()).then_some(j - 1)
        } else {
            None
        };
        if let Some(sep) = root.filter(|&s| tok(&tokens, s) == "::") {
            let next = tok(&tokens, sep + 1);
            if next == "{" {
                let mut level = 0;
                let mut j = sep + 1;
                while j < tokens.len() {
                    match tokens[j].0.as_str() {
                        "{" => level += 1,
                        "}" => level -= 1,
                        name if level == 1 && matches!(tok(&tokens, j - 1), "{" | ",") => {
                            push(tokens[j].1, name)
                        }
                        _ => {}
                    }
                    if level == 0 {
                        break;
                    }
                    j += 1;
                }
            } else {
                push(line, next);
            }
        }
        i += 1;
    }
    found
}

#[test]
fn references_are_found_in_code_only() {
    let modules: Vec<String> = ["config", "sim", "types", "mapping", "host"]
        .map(String::from)
        .to_vec();
    let text = r##"
use crate::config::Config; // crate::sim::x in a comment
use crate::{types::Vec3, mapping::{grid, scan}};
/* crate::sim::y in a block comment */
let s = "crate::sim::z in a string"; let r = r#"crate::sim::w"#; let c = '"';
fn f<'a>(x: &'a crate::types::Vec3) {}
mod tests { use super::super::config::X; use super::super::super::host::Y; }
"##;
    let found: Vec<(usize, String)> =
        references("safety", "src/safety/geofence.rs", text, 2, &modules)
            .into_iter()
            .map(|r| (r.line, r.to))
            .collect();
    let want = [
        (2, "config"),
        (3, "types"),
        (3, "mapping"),
        (6, "types"),
        (7, "host"),
    ];
    assert_eq!(
        found,
        want.map(|(l, m)| (l, m.to_string())).to_vec(),
        "from an inline module of a file two deep, the third super reaches the root: {found:?}"
    );
}
