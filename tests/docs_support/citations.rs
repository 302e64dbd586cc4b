//! The code a document's prose cites exists: every `` `path.rs::name` `` (and `path.rs::Type::method`) names a
//! Rust file of the workspace that defines each of the names, every `` `path.rs` `` names a file, and every
//! `` `Type::name` `` names a type the workspace defines with a `name` in the file that defines it, and every
//! `` `module::path::name` `` that starts with a workspace crate (`physics::…`, `skintight_knit::…`) or ends in
//! a module of one (`simulate::run`, `body::procedural_body`) names a module whose file — or, for a folder
//! module, one of its files — defines or re-exports the name (`Type::method` after a module, too).
//!
//! A cited path may be shortened from the left (`store/sqlite.rs`, `equilibrium.rs`): it matches every
//! workspace file whose path ends with it, and a name is found when one of those files defines it. "Defines"
//! is read from the text: `fn`, `struct`, `enum`, `trait`, `type`, `const`, `static`, `mod`, `macro_rules!`
//! followed by the name, or an enum variant / field (`name(`, `name {`, `name,` or `name:` at the start of a
//! line). Citations inside fenced blocks are left to the blocks' own checks; `foo.rs` stands for any file.

use std::path::{Path, PathBuf};

/// One Rust source of the workspace: its path relative to the repository root, and its text.
pub struct Source {
    pub path: String,
    pub text: String,
}

/// Every `.rs` file under `src/`, `crates/`, `tests/`, `benches/` and `examples/` of `root` (no `target/`).
pub fn workspace_sources(root: &Path) -> Vec<Source> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<Source>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for entry in entries.flatten() {
            let path = entry.path();
            let name = entry.file_name();
            if path.is_dir() {
                if name != "target" && !name.to_string_lossy().starts_with('.') {
                    walk(root, &path, out);
                }
            } else if path.extension().is_some_and(|e| e == "rs") {
                let text = std::fs::read_to_string(&path).unwrap_or_default();
                let rel = path.strip_prefix(root).unwrap_or(&path);
                out.push(Source {
                    path: rel.to_string_lossy().replace('\\', "/"),
                    text,
                });
            }
        }
    }
    let mut out = Vec::new();
    for top in ["src", "crates", "tests", "benches", "examples"] {
        walk(root, &root.join(top), &mut out);
    }
    out
}

/// The prose of a Markdown document: its text with the fenced blocks blanked (line numbers kept).
fn prose(markdown: &str) -> Vec<(usize, String)> {
    let mut fenced = false;
    let mut out = Vec::new();
    for (i, line) in markdown.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if !fenced {
            out.push((i + 1, line.to_string()));
        }
    }
    out
}

/// The inline code spans of a text (between single backticks).
fn code_spans(line: &str) -> Vec<&str> {
    line.split('`').skip(1).step_by(2).collect()
}

fn is_ident(s: &str) -> bool {
    !s.is_empty()
        && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        && !s.starts_with(|c: char| c.is_ascii_digit())
}

/// Whether `text` defines `name` (see the module doc).
fn defines(text: &str, name: &str) -> bool {
    const KEYWORDS: [&str; 9] = [
        "fn ",
        "struct ",
        "enum ",
        "trait ",
        "type ",
        "const ",
        "static ",
        "mod ",
        "macro_rules! ",
    ];
    let follows_ident_end =
        |rest: &str| !rest.starts_with(|c: char| c.is_ascii_alphanumeric() || c == '_');
    for keyword in KEYWORDS {
        let pattern = format!("{keyword}{name}");
        let mut from = 0;
        while let Some(at) = text[from..].find(&pattern) {
            let start = from + at;
            let end = start + pattern.len();
            let before_ok = start == 0
                || !text[..start].ends_with(|c: char| c.is_ascii_alphanumeric() || c == '_');
            if before_ok && follows_ident_end(&text[end..]) {
                return true;
            }
            from = end;
        }
    }
    text.lines().any(|line| {
        let t = line.trim_start().trim_start_matches("pub ");
        t.strip_prefix(name).is_some_and(|rest| {
            let rest = rest.trim_start();
            rest.starts_with('(')
                || rest.starts_with('{')
                || rest.starts_with(',')
                || rest.starts_with(':')
        })
    })
}

/// What one code span cites, if it cites code.
#[derive(Debug, PartialEq)]
enum Citation<'a> {
    /// `dir/file.rs` with the names after it (`::a::b`), possibly none.
    File { path: &'a str, names: Vec<&'a str> },
    /// `Type::name` (a type of the workspace, upper camel case, and one of its items).
    Item { ty: &'a str, name: &'a str },
    /// `module::…::name`, starting lower case (a module path, then an item or `Type::item`).
    Path { segments: Vec<&'a str> },
}

fn citation(span: &str) -> Option<Citation<'_>> {
    let span = span.trim().trim_end_matches("()");
    if let Some(at) = span.find(".rs") {
        let path = &span[..at + 3];
        let rest = &span[at + 3..];
        // `foo.rs` is the docs' placeholder for any file (the README's test convention).
        let placeholder = path == "foo.rs" || path.starts_with("foo/");
        if placeholder
            || path.contains(char::is_whitespace)
            || path.contains('*')
            || path.contains('{')
        {
            return None;
        }
        if rest.is_empty() {
            return Some(Citation::File {
                path,
                names: Vec::new(),
            });
        }
        let names: Vec<&str> = rest.strip_prefix("::")?.split("::").collect();
        if names.iter().all(|n| is_ident(n)) {
            return Some(Citation::File { path, names });
        }
        return None;
    }
    let parts: Vec<&str> = span.split("::").collect();
    if parts.len() == 2
        && parts.iter().all(|p| is_ident(p))
        && parts[0].starts_with(|c: char| c.is_ascii_uppercase())
        && parts[0].chars().any(|c| c.is_ascii_lowercase())
    {
        return Some(Citation::Item {
            ty: parts[0],
            name: parts[1],
        });
    }
    if parts.len() >= 2
        && parts.iter().all(|p| is_ident(p))
        && parts[0].starts_with(|c: char| c.is_ascii_lowercase())
    {
        return Some(Citation::Path { segments: parts });
    }
    None
}

/// The module path of a crate source (`crates/physics/src/cloth_on_body/hessian.rs` →
/// `physics::cloth_on_body::hessian`; the app's `src/…` under `skintight`), `None` for tests and examples.
fn module_path(path: &str) -> Option<Vec<String>> {
    let (krate, rest) = if let Some(rest) = path.strip_prefix("src/") {
        ("skintight".to_string(), rest)
    } else {
        let rest = path.strip_prefix("crates/")?;
        let (krate, rest) = rest.split_once('/')?;
        (krate.to_string(), rest.strip_prefix("src/")?)
    };
    let mut segments = vec![krate];
    let rest = rest.strip_suffix(".rs")?;
    segments.extend(
        rest.split('/')
            .filter(|s| !matches!(*s, "lib" | "mod" | "main"))
            .map(str::to_string),
    );
    Some(segments)
}

/// Checks a `module::…::name` citation; `None` when it holds or is not the workspace's.
fn check_path(segments: &[&str], sources: &[Source]) -> Option<String> {
    let first = segments[0]
        .strip_prefix("skintight_")
        .unwrap_or(segments[0]);
    let modules: Vec<(Vec<String>, &Source)> = sources
        .iter()
        .filter_map(|s| module_path(&s.path).map(|m| (m, s)))
        .collect();
    let ours = modules.iter().any(|(m, _)| m.iter().any(|x| x == first));
    if !ours {
        return None; // another crate's path (std, faer, tokio …)
    }
    // The longest module prefix that names a module of the workspace, read from the crate root
    // (`physics::…`) or as the tail of a module path (`simulate::…`).
    for split in (1..segments.len()).rev() {
        let wanted: Vec<&str> = std::iter::once(first)
            .chain(segments[1..split].iter().copied())
            .collect();
        let in_module = |m: &[String]| {
            m.len() >= wanted.len()
                && (0..=m.len() - wanted.len()).any(|at| {
                    m[at..at + wanted.len()]
                        .iter()
                        .zip(&wanted)
                        .all(|(a, b)| a == b)
                })
        };
        // The files of the module: the module's own file and, for a folder module, every file below it.
        let files: Vec<&Source> = modules
            .iter()
            .filter(|(m, _)| in_module(m))
            .map(|(_, s)| *s)
            .collect();
        if files.is_empty() {
            continue;
        }
        let rest = &segments[split..];
        let defined = |name: &str| {
            files.iter().any(|f| {
                defines(&f.text, name)
                    || f.text.lines().any(|l| {
                        l.trim_start().starts_with("pub use")
                            && l.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                                .any(|w| w == name)
                    })
            })
        };
        return match rest {
            [name] if defined(name) => None,
            [ty, name] if defined(ty) => {
                let owns = |s: &Source| {
                    defines(&s.text, ty)
                        || s.text.contains(&format!("impl {ty}"))
                        || s.text.contains(&format!(" for {ty}"))
                };
                (!sources.iter().any(|s| owns(s) && defines(&s.text, name)))
                    .then(|| format!("{ty} has no `{name}`"))
            }
            _ => Some(format!(
                "module {} defines no `{}`",
                segments[..split].join("::"),
                rest.join("::")
            )),
        };
    }
    Some(format!(
        "no module {}",
        segments[..segments.len() - 1].join("::")
    ))
}

/// Files whose path ends with the cited one (at a `/` boundary).
fn matching<'s>(sources: &'s [Source], path: &str) -> Vec<&'s Source> {
    sources
        .iter()
        .filter(|s| s.path == path || s.path.ends_with(&format!("/{path}")))
        .collect()
}

/// The citations of `markdown` (named `doc` in messages) that the sources do not bear out, one line each.
pub fn missing(doc: &str, markdown: &str, sources: &[Source]) -> Vec<String> {
    let mut out = Vec::new();
    for (line_no, line) in prose(markdown) {
        for span in code_spans(&line) {
            let Some(c) = citation(span) else { continue };
            let problem = match &c {
                Citation::File { path, names } => {
                    let files = matching(sources, path);
                    if files.is_empty() {
                        Some(format!("no file {path}"))
                    } else {
                        names
                            .iter()
                            .find(|n| !files.iter().any(|f| defines(&f.text, n)))
                            .map(|n| format!("{path} defines no `{n}`"))
                    }
                }
                Citation::Path { segments } => check_path(segments, sources),
                Citation::Item { ty, name } => {
                    let owns = |s: &Source| {
                        defines(&s.text, ty)
                            || s.text.contains(&format!("impl {ty}"))
                            || s.text.contains(&format!(" for {ty}"))
                    };
                    if !sources.iter().any(|s| defines(&s.text, ty)) {
                        Some(format!("no type {ty}"))
                    } else if !sources.iter().any(|s| owns(s) && defines(&s.text, name)) {
                        Some(format!("{ty} has no `{name}`"))
                    } else {
                        None
                    }
                }
            };
            if let Some(p) = problem {
                out.push(format!("{doc}:{line_no}: `{span}`: {p}"));
            }
        }
    }
    out
}

/// The documents whose prose is checked: the README and every `docs/*.md` but BENCHMARKS (a record of what was
/// measured when, which names the code of its time).
pub fn checked_documents(root: &Path) -> Vec<PathBuf> {
    let mut docs = vec![root.join("README.md")];
    let mut others: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .map(|d| d.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    others.retain(|p| p.extension().is_some_and(|e| e == "md") && !p.ends_with("BENCHMARKS.md"));
    others.sort();
    docs.extend(others);
    docs
}

#[cfg(test)]
mod tests {
    use super::*;

    fn planted() -> Vec<Source> {
        vec![
            Source {
                path: "crates/physics/src/equilibrium.rs".into(),
                text: "pub struct EquilibriumWorkspace;\nimpl EquilibriumWorkspace {\n    pub fn solve_hessian(&self) {}\n}\npub fn equilibrium_in() {}\npub enum StopReason {\n    Converged,\n    IterationLimit { n: usize },\n}\n".into(),
            },
            Source {
                path: "src/server/store/sqlite.rs".into(),
                text: "pub(crate) async fn claim() {}\n".into(),
            },
            Source {
                path: "crates/physics/src/lib.rs".into(),
                text: "pub mod equilibrium;\npub use equilibrium::{equilibrium_in, StopReason};\n".into(),
            },
            Source {
                path: "src/simulate/mod.rs".into(),
                text: "pub fn run_resumable() {}\n".into(),
            },
        ]
    }

    #[test]
    fn citations_that_exist_pass() {
        let doc = "`equilibrium.rs::equilibrium_in` and `physics/src/equilibrium.rs`, \
                   `store/sqlite.rs::claim`, `EquilibriumWorkspace::solve_hessian`, `StopReason::Converged`, \
                   `equilibrium.rs::EquilibriumWorkspace::solve_hessian`, `skintight simulate` (not code), \
                   `physics::equilibrium_in`, `skintight_physics::equilibrium::StopReason`, \
                   `physics::EquilibriumWorkspace::solve_hessian`, `simulate::run_resumable`, `std::fs::read`.\n\
                   ```text\n`gone.rs::nothing` in a figure\n```\n";
        assert_eq!(missing("doc.md", doc, &planted()), Vec::<String>::new());
    }

    #[test]
    fn the_check_sees_what_is_gone() {
        let doc = "`equilibrium.rs::equilibrium_gone`\n`scene.rs::parse_json`\n`EquilibriumWorkspace::gone`\n\
                   `NoSuchType::name`\n`sqlite.rs::EquilibriumWorkspace` and `quilibrium.rs`\n\
                   `simulate::run` `physics::equilibrium::gone` `server::queue::claim` `server::store::claim`\n";
        let got = missing("doc.md", doc, &planted());
        assert_eq!(
            got,
            vec![
                "doc.md:1: `equilibrium.rs::equilibrium_gone`: equilibrium.rs defines no `equilibrium_gone`",
                "doc.md:2: `scene.rs::parse_json`: no file scene.rs",
                "doc.md:3: `EquilibriumWorkspace::gone`: EquilibriumWorkspace has no `gone`",
                "doc.md:4: `NoSuchType::name`: no type NoSuchType",
                "doc.md:5: `sqlite.rs::EquilibriumWorkspace`: sqlite.rs defines no `EquilibriumWorkspace`",
                "doc.md:5: `quilibrium.rs`: no file quilibrium.rs",
                "doc.md:6: `simulate::run`: module simulate defines no `run`",
                "doc.md:6: `physics::equilibrium::gone`: module physics::equilibrium defines no `gone`",
                "doc.md:6: `server::queue::claim`: module server defines no `queue::claim`",
            ]
        );
    }

    #[test]
    fn definitions_are_whole_words() {
        assert!(defines("pub fn run_resumable() {}", "run_resumable"));
        assert!(!defines("pub fn run_resumable() {}", "run"));
        assert!(!defines("pub fn rerun() {}", "run"));
        assert!(defines("enum A {\n    Converged,\n}", "Converged"));
    }
}
