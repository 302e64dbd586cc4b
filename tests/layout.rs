//! The layout rules of the workspace (README, "Layout"; docs/ARCHITECTURE.md), checked on the source tree:
//!
//! - no source file imports another that imports it back, in any crate (a module's `pub use` of its own
//!   descendants is its facade, not an import; inline `#[cfg(test)] mod tests` blocks are left out);
//! - one test convention: no `#[path = …]` module files and no `*_tests.rs` files;
//! - the numeric crates never depend on tokio, sqlx or axum, and physics (with geometry under it) never on
//!   spade, the garment crate's triangulator;
//! - `cloth_on_body/` keeps its files under 900 lines;
//! - all SQL of the service is behind its store (`src/server/store.rs`, `src/server/store/`);
//! - one meaning per public type name: no two `pub struct|enum|trait|type|union NAME` anywhere in the
//!   workspace's sources (`src/`, `crates/*/src/`) share a NAME. Only plain `pub` counts: a `pub(crate)` or
//!   `pub(super)` name is seen only inside its crate, where the compiler already keeps it apart; a public
//!   name is what a reader meets in another crate's imports, the docs and the API, and there one name must
//!   mean one thing. Inline test modules count too (a test's public type is still read by name).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

type Module = Vec<String>;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let path = entry.expect("a directory entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The module path of a file under a crate's `src/` (`mesh/io/mod.rs` → `[mesh, io]`; `lib.rs` → `[]`).
fn module_of(src: &Path, file: &Path) -> Module {
    let rel = file.strip_prefix(src).expect("a file under src");
    let mut segs: Module = rel
        .with_extension("")
        .iter()
        .map(|s| s.to_string_lossy().into_owned())
        .collect();
    if matches!(
        segs.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        segs.pop();
    }
    segs
}

/// The code without line comments and without an inline `#[cfg(test)] mod tests { … }` at its end.
fn code_of(text: &str) -> String {
    let text = match text.find("#[cfg(test)]\nmod tests {") {
        Some(k) => &text[..k],
        None => text,
    };
    text.lines()
        .map(|l| match l.find("//") {
            Some(k) => &l[..k],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Expands a `use` tree (`a::{b, c::{d, e as f}}`) into its paths.
fn expand(prefix: &str, tree: &str) -> Vec<String> {
    let tree = tree.trim();
    let Some(open) = tree.find('{') else {
        let path = tree.split(" as ").next().unwrap_or(tree).trim();
        return vec![format!("{prefix}{path}")];
    };
    let head = &tree[..open];
    let body = &tree[open + 1..tree.rfind('}').unwrap_or(tree.len())];
    let (mut parts, mut depth, mut current) = (Vec::new(), 0, String::new());
    for c in body.chars() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            _ => {}
        }
        if c == ',' && depth == 0 {
            parts.push(std::mem::take(&mut current));
        } else {
            current.push(c);
        }
    }
    parts.push(current);
    parts
        .iter()
        .filter(|p| !p.trim().is_empty())
        .flat_map(|p| expand(&format!("{prefix}{head}"), p))
        .collect()
}

fn is_ident(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// `(path, public)` for every `use` item and every inline `crate::…`/`super::…` path of the code.
fn paths(code: &str) -> Vec<(String, bool)> {
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(k) = code[from..].find("use ") {
        let at = from + k;
        from = at + 4;
        let line_start = code[..at].rfind('\n').map_or(0, |i| i + 1);
        let before = code[line_start..at].trim();
        if !(before.is_empty() || before.starts_with("pub")) {
            continue;
        }
        let end = code[at..].find(';').map_or(code.len(), |e| at + e);
        let tree = code[at + 4..end]
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ");
        let public = before.starts_with("pub");
        out.extend(expand("", &tree).into_iter().map(|p| (p, public)));
    }
    for prefix in ["crate::", "super::"] {
        let mut from = 0;
        while let Some(k) = code[from..].find(prefix) {
            let at = from + k;
            from = at + prefix.len();
            if code[..at].ends_with(|c: char| is_ident(c) || c == ':') {
                continue;
            }
            let len = code[at..]
                .find(|c: char| !(is_ident(c) || c == ':'))
                .unwrap_or(code.len() - at);
            out.push((code[at..at + len].trim_end_matches(':').to_string(), false));
        }
    }
    out
}

/// The modules of one crate's `src/` and, for each, the modules it imports.
fn import_graph(src: &Path) -> BTreeMap<Module, BTreeSet<Module>> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    // The binary's `main.rs` only calls the library.
    files.retain(|f| f.file_name().is_none_or(|n| n != "main.rs"));
    let modules: BTreeMap<Module, PathBuf> = files
        .iter()
        .map(|f| (module_of(src, f), f.clone()))
        .collect();
    let mut graph = BTreeMap::new();
    for (module, file) in &modules {
        let mut deps = BTreeSet::new();
        if module.last().map(String::as_str) != Some("tests") {
            let text = std::fs::read_to_string(file).expect("a readable source");
            for (path, public) in paths(&code_of(&text)) {
                let mut segs: Vec<&str> = path.split("::").filter(|s| !s.is_empty()).collect();
                let mut base = module.clone();
                match segs.first() {
                    Some(&"crate") => {
                        base.clear();
                        segs.remove(0);
                    }
                    Some(&"super" | &"self") => {
                        while let Some(&s) = segs.first() {
                            match s {
                                "super" => {
                                    base.pop();
                                }
                                "self" => {}
                                _ => break,
                            }
                            segs.remove(0);
                        }
                    }
                    _ => continue,
                }
                let full: Module = base
                    .into_iter()
                    .chain(segs.iter().map(|s| s.to_string()))
                    .collect();
                let Some(target) = (0..=full.len())
                    .rev()
                    .map(|n| full[..n].to_vec())
                    .find(|m| modules.contains_key(m))
                else {
                    continue;
                };
                // A module's re-export of its own descendants is its facade.
                let facade = public && target.starts_with(module);
                if target != *module && !facade {
                    deps.insert(target);
                }
            }
        }
        graph.insert(module.clone(), deps);
    }
    graph
}

/// A cycle of the graph, if it has one.
fn find_cycle(graph: &BTreeMap<Module, BTreeSet<Module>>) -> Option<Vec<Module>> {
    fn visit(
        m: &Module,
        graph: &BTreeMap<Module, BTreeSet<Module>>,
        done: &mut BTreeMap<Module, bool>,
        stack: &mut Vec<Module>,
    ) -> Option<Vec<Module>> {
        match done.get(m) {
            Some(true) => return None,
            Some(false) => {
                let from = stack.iter().position(|s| s == m).expect("on the stack");
                return Some(stack[from..].iter().chain([m]).cloned().collect());
            }
            None => {}
        }
        done.insert(m.clone(), false);
        stack.push(m.clone());
        for d in &graph[m] {
            if let Some(cycle) = visit(d, graph, done, stack) {
                return Some(cycle);
            }
        }
        stack.pop();
        done.insert(m.clone(), true);
        None
    }
    let mut done = BTreeMap::new();
    graph
        .keys()
        .find_map(|m| visit(m, graph, &mut done, &mut Vec::new()))
}

/// The workspace's numeric crates (`crates/NAME`), bottom-up.
const NUMERIC_CRATES: [&str; 7] = [
    "geometry",
    "garment",
    "physics",
    "optimize",
    "design",
    "knit",
    "homogenize",
];

fn crate_sources() -> Vec<PathBuf> {
    let mut srcs = vec![root().join("src")];
    for name in NUMERIC_CRATES {
        srcs.push(root().join("crates").join(name).join("src"));
    }
    srcs
}

#[test]
fn no_source_file_imports_one_that_imports_it_back() {
    for src in crate_sources() {
        let graph = import_graph(&src);
        if let Some(cycle) = find_cycle(&graph) {
            let names: Vec<String> = cycle
                .iter()
                .map(|m| {
                    if m.is_empty() {
                        "(crate root)".into()
                    } else {
                        m.join("::")
                    }
                })
                .collect();
            panic!(
                "circular imports in {}: {}",
                src.display(),
                names.join(" → ")
            );
        }
    }
}

#[test]
fn the_cycle_finder_sees_a_cycle() {
    // The checker can fail: two files importing each other, and a facade that does not count.
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path();
    std::fs::create_dir_all(src.join("a")).unwrap();
    std::fs::write(
        src.join("lib.rs"),
        "pub mod a;\npub mod b;\npub use a::A;\n",
    )
    .unwrap();
    std::fs::write(src.join("a/mod.rs"), "use crate::b::B;\npub struct A;\n").unwrap();
    std::fs::write(src.join("b.rs"), "pub struct B;\n").unwrap();
    assert!(find_cycle(&import_graph(src)).is_none());
    std::fs::write(
        src.join("b.rs"),
        "use super::a::{self, A};\npub struct B;\n",
    )
    .unwrap();
    let cycle = find_cycle(&import_graph(src)).expect("a ↔ b");
    assert_eq!(cycle.len(), 3, "{cycle:?}");
}

#[test]
fn one_test_convention() {
    for src in crate_sources() {
        let mut files = Vec::new();
        rust_files(&src, &mut files);
        for f in files {
            let name = f.file_name().unwrap().to_string_lossy();
            assert!(
                !name.ends_with("_tests.rs"),
                "{}: tests go inline or in foo/tests.rs (README, Tests)",
                f.display()
            );
            let text = std::fs::read_to_string(&f).unwrap();
            assert!(
                !text.contains("#[path ="),
                "{}: a #[path] module; tests go inline or in foo/tests.rs",
                f.display()
            );
        }
    }
}

/// The names in a manifest's `[dependencies]` table.
fn dependencies(manifest: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(manifest).unwrap();
    let mut in_deps = false;
    let mut out = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        if line.starts_with('[') {
            in_deps = line == "[dependencies]";
        } else if in_deps
            && !line.starts_with('#')
            && let Some((name, _)) = line.split_once('=')
        {
            out.push(name.trim().trim_end_matches(".workspace").to_string());
        }
    }
    out
}

#[test]
fn numeric_crates_stay_numeric() {
    for name in NUMERIC_CRATES {
        let deps = dependencies(&root().join("crates").join(name).join("Cargo.toml"));
        assert!(deps.iter().any(|d| d == "thiserror"), "{name}: {deps:?}");
        for web in ["tokio", "sqlx", "axum", "tower", "tower-http"] {
            assert!(
                !deps.iter().any(|d| d == web),
                "crates/{name} depends on {web}"
            );
        }
        let spade = deps.iter().any(|d| d == "spade");
        assert_eq!(
            spade,
            name == "garment",
            "crates/{name}: spade belongs to the garment crate"
        );
    }
    let physics = dependencies(&root().join("crates/physics/Cargo.toml"));
    assert!(
        !physics.iter().any(|d| d == "skintight-garment"),
        "physics must not wait for the garment crate"
    );
}

#[test]
fn cloth_on_body_files_stay_small() {
    let dir = root().join("crates/physics/src/cloth_on_body");
    let mut files = Vec::new();
    rust_files(&dir, &mut files);
    assert!(files.len() >= 5, "{files:?}");
    for f in files {
        let lines = std::fs::read_to_string(&f).unwrap().lines().count();
        assert!(lines <= 900, "{}: {lines} lines", f.display());
    }
}

#[test]
fn all_sql_is_in_the_store() {
    let server = root().join("src/server");
    let mut files = Vec::new();
    rust_files(&server, &mut files);
    assert!(files.len() > 10, "{files:?}");
    for f in files {
        if f.starts_with(server.join("store")) || f == server.join("store.rs") {
            continue;
        }
        let text = std::fs::read_to_string(&f).unwrap();
        for needle in ["sqlx::query", "SqlitePool"] {
            assert!(
                !text.contains(needle),
                "{} uses {needle}: move the query into src/server/store",
                f.display()
            );
        }
    }
}

/// The public type names (`pub struct|enum|trait|type|union NAME`) a source defines, in order.
fn public_types(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for line in code_of_all(text).lines() {
        let Some(rest) = line.trim_start().strip_prefix("pub ") else {
            continue;
        };
        let mut words = rest.split_whitespace();
        if let (Some("struct" | "enum" | "trait" | "type" | "union"), Some(name)) =
            (words.next(), words.next())
        {
            let name: String = name.chars().take_while(|&c| is_ident(c)).collect();
            if !name.is_empty() {
                out.push(name);
            }
        }
    }
    out
}

/// The code without line comments (inline test modules kept).
fn code_of_all(text: &str) -> String {
    text.lines()
        .map(|l| match l.find("//") {
            Some(k) => &l[..k],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Each public type name defined more than once under `srcs`, with the files (relative to `base`) that
/// define it.
fn names_defined_twice(base: &Path, srcs: &[PathBuf]) -> BTreeMap<String, Vec<String>> {
    let mut defined: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for src in srcs {
        let mut files = Vec::new();
        rust_files(src, &mut files);
        files.sort();
        for f in files {
            let text = std::fs::read_to_string(&f).expect("a readable source");
            let rel = f.strip_prefix(base).unwrap_or(&f).display().to_string();
            for name in public_types(&text) {
                defined.entry(name).or_default().push(rel.clone());
            }
        }
    }
    defined.retain(|_, files| files.len() > 1);
    defined
}

#[test]
fn one_meaning_per_public_type_name() {
    // Every crate of the workspace, also one added after this test was written.
    let mut srcs = vec![root().join("src")];
    for entry in std::fs::read_dir(root().join("crates")).unwrap() {
        let src = entry.unwrap().path().join("src");
        if src.is_dir() {
            srcs.push(src);
        }
    }
    let twice = names_defined_twice(root(), &srcs);
    let list: Vec<String> = twice
        .iter()
        .map(|(name, files)| format!("{name}: {}", files.join(", ")))
        .collect();
    assert!(
        twice.is_empty(),
        "public type names defined more than once (rename each so that it says what it is):\n  {}",
        list.join("\n  ")
    );
}

#[test]
fn the_name_check_sees_a_name_defined_twice() {
    // The checker can fail: two crates that both define a public `Region`; crate-private and commented-out
    // definitions do not count.
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a/src"), dir.path().join("b/src"));
    std::fs::create_dir_all(a.join("shape")).unwrap();
    std::fs::create_dir_all(&b).unwrap();
    std::fs::write(
        a.join("shape/region.rs"),
        "/// A half-space region.\npub struct Region {\n    pub half_spaces: Vec<f64>,\n}\n",
    )
    .unwrap();
    std::fs::write(
        b.join("lib.rs"),
        "pub(crate) struct Region;\n// pub enum Region {}\npub struct Band;\n",
    )
    .unwrap();
    let srcs = [a.clone(), b.clone()];
    assert!(names_defined_twice(dir.path(), &srcs).is_empty());
    std::fs::write(
        b.join("pressure.rs"),
        "#[derive(Debug)]\npub enum Region<'a> { Band(&'a str) }\n",
    )
    .unwrap();
    let twice = names_defined_twice(dir.path(), &srcs);
    assert_eq!(
        twice.into_iter().collect::<Vec<_>>(),
        vec![(
            "Region".to_string(),
            vec![
                "a/src/shape/region.rs".to_string(),
                "b/src/pressure.rs".to_string()
            ]
        )]
    );
}
