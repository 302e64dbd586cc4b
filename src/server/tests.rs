//! Layout checks of the server's modules: no two import each other (directly or through others), and
//! no SQL outside [`super::store`]. The import graph is read from the sources: `use` items and inline
//! `super::…` / `crate::server::…` paths, outside comments.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Every `.rs` file under `dir`, recursively.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("src/server is readable") {
        let path = entry.expect("a directory entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The module path of a file relative to `src/server` (`store::jobs`; the root `mod.rs` is `""`).
fn module_of(root: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(root).expect("a file under the root");
    let mut parts: Vec<String> = rel
        .with_extension("")
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if parts.last().is_some_and(|p| p == "mod") {
        parts.pop();
    }
    parts
}

fn is_ident(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

/// The paths of a `use` tree (`a::{b, c::{d, e}}` gives `a::b`, `a::c::d`, `a::c::e`).
fn expand(prefix: &str, tree: &str) -> Vec<String> {
    let tree = tree.trim();
    let join = |p: &str, s: &str| {
        if p.is_empty() {
            s.to_string()
        } else {
            format!("{p}::{s}")
        }
    };
    let Some(open) = tree.find('{') else {
        let item = tree.split(" as ").next().unwrap_or("").trim();
        return match item {
            "self" => vec![prefix.to_string()],
            _ => vec![join(prefix, item)],
        };
    };
    let head = tree[..open].trim_end_matches("::");
    let inner = &tree[open + 1..tree.rfind('}').expect("a closing brace")];
    let prefix = join(prefix, head);
    let (mut depth, mut start, mut out) = (0, 0, Vec::new());
    for (i, c) in inner.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                out.extend(expand(&prefix, &inner[start..i]));
                start = i + 1;
            }
            _ => {}
        }
    }
    if !inner[start..].trim().is_empty() {
        out.extend(expand(&prefix, &inner[start..]));
    }
    out
}

/// The modules a file imports (absolute module paths, each a file of `modules`).
fn imports(
    module: &[String],
    text: &str,
    modules: &BTreeSet<Vec<String>>,
) -> BTreeSet<Vec<String>> {
    let code: String = text
        .lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n");
    let tests_at = code.find("mod tests {").unwrap_or(code.len());
    let children: BTreeSet<&str> = code
        .lines()
        .filter_map(|l| {
            let l = l.trim();
            let l = l.strip_prefix("pub ").unwrap_or(l);
            l.strip_prefix("mod ")?.strip_suffix(';')
        })
        .collect();
    let mut paths: Vec<(usize, String)> = Vec::new();
    // `use` items.
    let mut from = 0;
    while let Some(k) = code[from..].find("use ") {
        let at = from + k;
        from = at + 4;
        // Only `use` items: at the start of a line, after an optional visibility.
        let line_start = code[..at].rfind('\n').map_or(0, |i| i + 1);
        let before = code[line_start..at].trim();
        if !(before.is_empty() || before.starts_with("pub")) {
            continue;
        }
        let end = code[at..].find(';').map_or(code.len(), |e| at + e);
        let tree: String = code[at + 4..end]
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ");
        for p in expand("", &tree) {
            paths.push((at, p));
        }
    }
    // Inline paths.
    for prefix in ["super::", "crate::server::"] {
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
            let path = code[at..at + len].trim_end_matches(':');
            if !path.ends_with("super") {
                paths.push((at, path.to_string()));
            }
        }
    }
    let mut out = BTreeSet::new();
    for (at, path) in paths {
        let mut segs: Vec<&str> = path.split("::").filter(|s| !s.is_empty()).collect();
        // Inside the inline test module `super` is this file.
        if at > tests_at && segs.first() == Some(&"super") {
            segs[0] = "self";
        }
        let mut base: Vec<String> = module.to_vec();
        match segs.first() {
            Some(&"crate") if segs.get(1) == Some(&"server") => {
                base.clear();
                segs.drain(..2);
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
            Some(s) if children.contains(s) => {}
            _ => continue,
        }
        if segs.is_empty() {
            continue;
        }
        let full: Vec<String> = base
            .into_iter()
            .chain(segs.iter().map(|s| s.to_string()))
            .collect();
        if let Some(target) = (0..=full.len())
            .rev()
            .map(|n| full[..n].to_vec())
            .find(|m| modules.contains(m))
            && target != module
        {
            out.insert(target);
        }
    }
    out
}

fn server_sources() -> (PathBuf, Vec<PathBuf>) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/server");
    let mut files = Vec::new();
    rust_files(&root, &mut files);
    files.sort();
    (root, files)
}

fn name(m: &[String]) -> String {
    if m.is_empty() {
        "server".to_string()
    } else {
        m.join("::")
    }
}

#[test]
fn no_module_imports_one_that_imports_it_back() {
    let (root, files) = server_sources();
    let modules: BTreeSet<Vec<String>> = files.iter().map(|f| module_of(&root, f)).collect();
    let graph: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = files
        .iter()
        .map(|f| {
            let m = module_of(&root, f);
            let text = std::fs::read_to_string(f).expect("a readable source");
            let deps = imports(&m, &text, &modules);
            (m, deps)
        })
        .collect();
    // The reader sees imports (a `use super::queue` in the worker).
    assert!(graph[&vec!["worker".to_string()]].contains(&vec!["queue".to_string()]));
    // Depth-first search for a back edge.
    fn visit(
        m: &Vec<String>,
        graph: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
        state: &mut BTreeMap<Vec<String>, bool>,
        stack: &mut Vec<Vec<String>>,
    ) -> Option<Vec<String>> {
        match state.get(m) {
            Some(true) => return None,
            Some(false) => {
                let from = stack.iter().position(|s| s == m).expect("on the stack");
                return Some(stack[from..].iter().chain([m]).map(|s| name(s)).collect());
            }
            None => {}
        }
        state.insert(m.clone(), false);
        stack.push(m.clone());
        for d in &graph[m] {
            if let Some(cycle) = visit(d, graph, state, stack) {
                return Some(cycle);
            }
        }
        stack.pop();
        state.insert(m.clone(), true);
        None
    }
    let mut state = BTreeMap::new();
    for m in graph.keys() {
        let cycle = visit(m, &graph, &mut state, &mut Vec::new());
        assert!(
            cycle.is_none(),
            "circular imports in src/server: {}",
            cycle.unwrap_or_default().join(" → ")
        );
    }
}

#[test]
fn all_sql_is_in_the_store() {
    let (root, files) = server_sources();
    let store = root.join("store");
    for f in &files {
        if f.starts_with(&store) || *f == root.join("store.rs") || *f == root.join("tests.rs") {
            continue;
        }
        let text = std::fs::read_to_string(f).expect("a readable source");
        for needle in ["sqlx::query", "SqlitePool"] {
            assert!(
                !text.contains(needle),
                "{} uses {needle}: move the query into src/server/store",
                f.display()
            );
        }
    }
}
