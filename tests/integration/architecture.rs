//! The architecture test (docs/architecture.md), for what the compiler cannot see.
//!
//! The layers are crates: a crate names its dependencies in its `Cargo.toml` and cannot
//! `use` any other crate (an upward `use` does not compile: each layer crate's docs hold
//! a `compile_fail` example of one), and Cargo refuses a loop between crates. What is
//! left to check here:
//!
//! - the crate graph is the one `docs/architecture.md` draws (its table of crates), so
//!   the picture cannot drift from the `Cargo.toml` files;
//! - inside the math crate, whose modules are layers of their own (`poly` →
//!   `moments`, `sdp` → `contour`, `relax` → `mc`), no module uses one of its layer or
//!   above;
//! - inside every crate, no loop between files: the `crate::…` and `super::…` paths of
//!   each file (comments skipped) read as edges between modules. It reads the source
//!   text, not the compiler's view: it sees paths written out, not names that reach a
//!   file through a re-export of its parent module.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The workspace's riskplan crates and the riskplan crates each depends on (its
/// `[dependencies]`; dev-dependencies are the tests' own).
fn declared_graph(root: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let mut out = BTreeMap::new();
    let mut manifests = vec![root.join("Cargo.toml")];
    for e in std::fs::read_dir(root.join("crates")).unwrap() {
        manifests.push(e.unwrap().path().join("Cargo.toml"));
    }
    for m in manifests {
        let text = std::fs::read_to_string(&m).unwrap();
        let name = text
            .lines()
            .find_map(|l| l.strip_prefix("name = \""))
            .and_then(|l| l.strip_suffix('"'))
            .unwrap()
            .to_string();
        let mut deps = BTreeSet::new();
        let mut section = "";
        for l in text.lines() {
            let l = l.trim();
            if l.starts_with('[') {
                section = l;
            } else if section == "[dependencies]" && l.starts_with("riskplan") {
                deps.insert(l.split([' ', '=']).next().unwrap().to_string());
            }
        }
        out.insert(name, deps);
    }
    out
}

/// The crate table of docs/architecture.md: rows `| crate | riskplan crates it uses | … |`
/// between the lines `<!-- crate graph -->` and `<!-- end crate graph -->`.
fn documented_graph(root: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let text = std::fs::read_to_string(root.join("docs/architecture.md")).unwrap();
    let start = text.find("<!-- crate graph -->").expect("docs/architecture.md has no <!-- crate graph --> table");
    let end = text.find("<!-- end crate graph -->").expect("the crate graph table has no end marker");
    let mut out = BTreeMap::new();
    for row in text[start..end].lines().filter(|l| l.starts_with("| `")) {
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        let name = cells[1].trim_matches('`').to_string();
        let deps = cells[2]
            .split(',')
            .map(|d| d.trim().trim_matches('`').to_string())
            .filter(|d| !d.is_empty() && d != "—")
            .collect();
        out.insert(name, deps);
    }
    out
}

#[test]
fn the_crate_graph_is_the_one_the_architecture_page_draws() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let declared = declared_graph(root);
    let documented = documented_graph(root);
    assert_eq!(
        declared, documented,
        "the Cargo.toml files (left) and docs/architecture.md's crate table (right) differ"
    );
}

/// The math crate's module layers, bottom to top: a module may use only modules of
/// lower layers.
const MATH_LAYERS: &[&[&str]] = &[&["poly"], &["moments", "sdp"], &["contour", "relax"], &["mc"]];

fn layer_of(module: &str) -> Option<usize> {
    MATH_LAYERS.iter().position(|l| l.contains(&module))
}

/// `src/a/b/c.rs` → `a::b::c`; `src/a/b/mod.rs` → `a::b`; `src/a.rs` → `a`.
fn module_path(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = rel.iter().map(|p| p.to_string_lossy().into_owned()).collect();
    if parts.last().is_some_and(|p| p == "mod") {
        parts.pop();
    }
    parts.join("::")
}

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

/// The code of a file without its comments (line comments and doc comments).
fn code(text: &str) -> String {
    text.lines().map(|l| l.split("//").next().unwrap_or("")).collect::<Vec<_>>().join("\n")
}

/// Every `prefix` path in `code` as its `::`-separated segments (`crate::a::{b, c}` → `[a]`).
fn paths(code: &str, prefix: &str) -> Vec<Vec<String>> {
    code.match_indices(prefix)
        .filter(|(i, _)| !code[..*i].ends_with(|c: char| c.is_alphanumeric() || c == '_' || c == ':'))
        .map(|(i, _)| {
            let rest = &code[i + prefix.len()..];
            let end = rest.find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':')).unwrap_or(rest.len());
            rest[..end].split("::").filter(|s| !s.is_empty()).map(str::to_string).collect()
        })
        .collect()
}

/// Edges between the modules of one crate's tree: (from, to) module paths, resolved to
/// the longest known module. Edges between a module and its own ancestors are not kept
/// (a folder owns its files; files use what their parent re-exports).
fn edges(src: &Path) -> BTreeSet<(String, String)> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let modules: BTreeSet<String> = files.iter().map(|f| module_path(src, f)).collect();
    let resolve = |segs: &[String]| -> Option<String> {
        (1..=segs.len()).rev().map(|n| segs[..n].join("::")).find(|m| modules.contains(m))
    };
    let mut out = BTreeSet::new();
    for f in &files {
        let from = module_path(src, f);
        if from == "lib" || from == "main" {
            continue;
        }
        let text = code(&std::fs::read_to_string(f).unwrap());
        let me: Vec<String> = from.split("::").map(str::to_string).collect();
        let mut targets = Vec::new();
        for p in paths(&text, "crate::") {
            targets.extend(resolve(&p));
        }
        for p in paths(&text, "super::") {
            // `super` is the module's parent, whether the module is a file or a folder
            let mut up = me[..me.len() - 1].to_vec();
            let mut p = p;
            while p.first().is_some_and(|s| s == "super") {
                p.remove(0);
                up.pop();
            }
            up.extend(p);
            targets.extend(resolve(&up));
        }
        for to in targets {
            let related = from == to || from.starts_with(&format!("{to}::")) || to.starts_with(&format!("{from}::"));
            if !related {
                out.insert((from.clone(), to));
            }
        }
    }
    out
}

fn top(m: &str) -> &str {
    m.split("::").next().unwrap_or(m)
}

/// The loops among the files of one crate's tree, and with `layered` the imports
/// (`from → to` between top-level modules) that run upward or within one layer of
/// [`MATH_LAYERS`].
fn violations(src: &Path, layered: bool) -> Vec<String> {
    let edges = edges(src);
    let mut bad = Vec::new();
    for (from, to) in edges.iter().filter(|_| layered) {
        let (a, b) = (top(from), top(to));
        if a == b {
            continue;
        }
        match (layer_of(a), layer_of(b)) {
            (Some(la), Some(lb)) if lb < la => {}
            (Some(_), Some(_)) => bad.push(format!("{from} uses {to}: `{b}` is not below `{a}`")),
            _ => bad.push(format!("{from} uses {to}: a module missing from MATH_LAYERS")),
        }
    }
    // loops: depth-first search over the module graph
    let mut graph: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    for (from, to) in &edges {
        graph.entry(from).or_default().push(to);
    }
    fn visit<'a>(
        n: &'a str,
        g: &BTreeMap<&'a str, Vec<&'a str>>,
        state: &mut BTreeMap<&'a str, u8>,
        stack: &mut Vec<&'a str>,
        bad: &mut Vec<String>,
    ) {
        state.insert(n, 1);
        stack.push(n);
        for &m in g.get(n).into_iter().flatten() {
            match state.get(m) {
                Some(1) => {
                    let at = stack.iter().position(|&s| s == m).unwrap_or(0);
                    bad.push(format!("loop: {} -> {m}", stack[at..].join(" -> ")));
                }
                Some(_) => {}
                None => visit(m, g, state, stack, bad),
            }
        }
        stack.pop();
        state.insert(n, 2);
    }
    let mut state = BTreeMap::new();
    let nodes: Vec<&str> = graph.keys().copied().collect();
    for n in nodes {
        if !state.contains_key(n) {
            visit(n, &graph, &mut state, &mut Vec::new(), &mut bad);
        }
    }
    bad
}

/// Every riskplan crate's source folder (the root package's `src/` too).
fn crate_sources(root: &Path) -> Vec<PathBuf> {
    let mut out = vec![root.join("src")];
    for e in std::fs::read_dir(root.join("crates")).unwrap() {
        let src = e.unwrap().path().join("src");
        if src.is_dir() {
            out.push(src);
        }
    }
    out
}

#[test]
fn no_loop_in_any_crate_and_the_math_layers_hold() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut bad = Vec::new();
    for src in crate_sources(root) {
        let layered = src.ends_with("riskplan-math/src");
        bad.extend(violations(&src, layered).into_iter().map(|b| format!("{}: {b}", src.display())));
    }
    assert!(bad.is_empty(), "architecture violations:\n{}", bad.join("\n"));
}

/// The test itself can fail: a copy of the math crate with one upward import injected
/// (the polynomials using the Monte Carlo estimates) and one loop between two files is
/// refused.
#[test]
fn an_injected_upward_import_fails() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("crates/riskplan-math/src");
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    for f in &files {
        let to = copy.join(f.strip_prefix(&src).unwrap());
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        std::fs::copy(f, &to).unwrap();
    }
    let ring = copy.join("poly/ring.rs");
    let text = std::fs::read_to_string(&ring).unwrap();
    std::fs::write(&ring, format!("{text}\nuse crate::mc::McModel;\nuse super::interval::Interval;\n")).unwrap();
    let bad = violations(&copy, true);
    assert!(bad.iter().any(|b| b.starts_with("poly::ring uses mc")), "{bad:?}");
    assert!(
        bad.iter().any(|b| b.starts_with("loop:") && b.contains("poly::ring") && b.contains("poly::interval")),
        "{bad:?}"
    );
}
