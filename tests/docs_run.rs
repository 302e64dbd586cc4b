//! Docs that run: every fenced block of `README.md` and `docs/*.md` is checked against the code, so a renamed
//! key, a changed flag or a scene that no longer solves shows here rather than on a reader's machine.
//!
//! - `json` blocks parse. A scene passes `Scene::from_json` (parse and validate); a design job passes
//!   `DesignJob::from_json`; an error envelope has `code`, `field` and `message`. Relative mesh paths resolve
//!   against the repository root or `examples/`. A block whose heading names one
//!   `examples/NAME.json` must be that example (compared after parsing, so defaults may be left out). A scene on
//!   a procedural body is simulated with the built binary. A block marked `<!-- fragment -->` just before it is
//!   only parsed.
//! - Command blocks (`sh`, `bash`, `shell`, `console`) run with bash in a temporary directory that mirrors the
//!   repository (so `examples/…`, `../shared/data/…` and `out/…` work) with `/tmp/` mapped into it;
//!   `cargo run [--release] --`, `./target/*/skintight` and `skintight` call the binary under test and
//!   `cargo build` is a no-op (the binary is built).
//!   * Quick blocks (`mesh`, `body`, `simulate` of the quick scenes) run for real and must exit 0.
//!   * Long blocks (`design`, `simulate` of the pants, the scripts of `tools/`) run for real only in the
//!     ignored test
//!     `long_blocks_run_for_real` (`cargo test --test docs_run -- --ignored`; `DOCS_RUN_BLOCK=FILE:LINE` picks
//!     one block); by default every `skintight` call in them runs with its input replaced by a file that does
//!     not exist and must exit 2 naming that file — so the subcommand and the flags still parse — and every
//!     `tools/` script must pass `bash -n`.
//!   * Service blocks: the document's `skintight serve` block starts the real server on a free loopback port
//!     (its own temporary database); then the `curl` blocks run in document order with `localhost:8080`
//!     pointing at it, shell variables (`ASSET`, `JOB`) carried from block to block. Each must exit 0, print
//!     every JSON key and SSE event name its `#` comment lines show, and print no error envelope unless its
//!     comments show one. The README's job must end `completed` with its artifacts downloaded.
//!   * `cargo test --workspace` is the command of `.ci/run`, which runs this test; `docker` blocks are checked
//!     against `docker/Dockerfile` (and built in the ignored test when docker runs).
//!
//!   Any other block fails the test, naming its file and line.
//! - The prose's citations of code exist (`cited_code_exists`, `docs_support/citations.rs`): every
//!   `` `path.rs::name` ``, `` `module::name` `` and `` `Type::name` `` of the README and `docs/*.md` (but
//!   BENCHMARKS, a record of its time) names code the workspace defines.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;
use skintight::design::DesignJob;
use skintight::scene::Scene;

/// Scenes quick enough to simulate in every test run (a few seconds in the test profile).
const QUICK_SCENES: [&str; 3] = ["cylinder", "sphere", "calf_sleeve"];
/// What the docs' placeholder `X` (an example name) stands for when a long block runs for real.
const EXAMPLE_PLACEHOLDER: &str = "design_cylinder_tapered";
/// Exit status of the command-line tool for unusable input.
const UNUSABLE_INPUT: i32 = 2;

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// `../shared` beside the checkout (the body scans), as the examples expect.
fn shared() -> PathBuf {
    repo()
        .ancestors()
        .map(|a| a.join("shared"))
        .find(|d| d.join("data/bodies").is_dir())
        .expect("shared/data/bodies beside the checkout (see the README's prerequisites)")
}

/// One fenced block of a document.
#[derive(Clone, Debug)]
struct Block {
    /// The document, relative to the repository root.
    file: String,
    /// 1-based line of the opening fence.
    line: usize,
    lang: String,
    text: String,
    /// The HTML comment on the line before the fence, if any.
    marker: Option<String>,
    /// The nearest heading above the block.
    heading: String,
}

impl Block {
    fn at(&self) -> String {
        format!("{}:{}", self.file, self.line)
    }
}

fn documents() -> Vec<String> {
    let mut docs = vec!["README.md".to_string()];
    let mut more: Vec<String> = std::fs::read_dir(repo().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".md"))
        .map(|n| format!("docs/{n}"))
        .collect();
    more.sort();
    docs.extend(more);
    docs
}

fn blocks() -> Vec<Block> {
    let mut out = Vec::new();
    for file in documents() {
        let text = std::fs::read_to_string(repo().join(&file)).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        let mut open: Option<(usize, String)> = None;
        let mut heading = "";
        for (i, l) in lines.iter().enumerate() {
            let t = l.trim_start();
            if !t.starts_with("```") {
                if open.is_none() && l.starts_with('#') {
                    heading = l;
                }
                continue;
            }
            match open.take() {
                None => open = Some((i, t[3..].trim().to_string())),
                Some((start, lang)) => {
                    let before = &lines[..start];
                    let marker = before
                        .iter()
                        .rev()
                        .find(|l| !l.trim().is_empty())
                        .filter(|l| l.trim_start().starts_with("<!--"))
                        .map(|l| l.trim().to_string());
                    out.push(Block {
                        file: file.clone(),
                        line: start + 1,
                        lang,
                        text: lines[start + 1..i].join("\n"),
                        marker,
                        heading: heading.to_string(),
                    });
                }
            }
        }
        assert!(open.is_none(), "{file}: a fenced block is not closed");
    }
    out
}

// ---------------------------------------------------------------------------------------------------------
// Shell blocks: what they are.

/// The commands of a shell block: continuation lines joined, comment lines and here-document bodies left out.
fn commands(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut current = String::new();
    let mut heredoc: Option<String> = None;
    for line in text.lines() {
        if let Some(end) = &heredoc {
            if line.trim_end() == end {
                heredoc = None;
            }
            continue;
        }
        let t = line.trim();
        if current.is_empty() && (t.is_empty() || t.starts_with('#')) {
            continue;
        }
        if let Some(k) = t.find("<<") {
            let word = t[k + 2..]
                .trim_start_matches('-')
                .trim()
                .trim_matches(|c| c == '\'' || c == '"');
            heredoc = Some(word.split_whitespace().next().unwrap_or("").to_string());
        }
        match t.strip_suffix('\\') {
            Some(head) => {
                current.push_str(head);
                current.push(' ');
            }
            None => {
                current.push_str(t);
                out.push(std::mem::take(&mut current));
            }
        }
    }
    if !current.is_empty() {
        out.push(current);
    }
    out
}

/// The words of a command after leading `VAR=value` assignments and `time`.
fn words(command: &str) -> Vec<&str> {
    command
        .split_whitespace()
        .skip_while(|w| {
            *w == "time"
                || w.split_once('=').is_some_and(|(k, _)| {
                    !k.is_empty() && k.chars().all(|c| c.is_ascii_uppercase() || c == '_')
                })
        })
        .collect()
}

/// The arguments of a `skintight` call in a command, if it is one.
fn skintight_args(command: &str) -> Option<Vec<String>> {
    let w = words(command);
    let rest: &[&str] = match w.as_slice() {
        ["cargo", "run", "--release", "--", rest @ ..] | ["cargo", "run", "--", rest @ ..] => rest,
        [bin, rest @ ..] if *bin == "skintight" || bin.ends_with("/skintight") => rest,
        _ => return None,
    };
    Some(rest.iter().map(|s| s.to_string()).collect())
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum ShellKind {
    /// `cargo test --workspace`: what `.ci/run` runs, and so what runs this test.
    Suite,
    /// `docker build` / `docker run`.
    Docker,
    /// `skintight serve`: starts the document's server.
    Server,
    /// `curl` against the server.
    Service,
    /// Command-line calls; `long` ones run for real only under `--ignored`.
    Cli { long: bool },
}

fn shell_kind(b: &Block) -> Result<ShellKind, String> {
    let cmds = commands(&b.text);
    if cmds.is_empty() {
        return Err("an empty command block".into());
    }
    if cmds == ["cargo test --workspace"] {
        return Ok(ShellKind::Suite);
    }
    if cmds.iter().all(|c| words(c).first() == Some(&"docker")) {
        return Ok(ShellKind::Docker);
    }
    let calls: Vec<Vec<String>> = cmds.iter().filter_map(|c| skintight_args(c)).collect();
    if calls.len() == 1 && calls[0].first().map(String::as_str) == Some("serve") && cmds.len() == 1
    {
        return Ok(ShellKind::Server);
    }
    if b.text.contains("curl ") {
        return Ok(ShellKind::Service);
    }
    let mut long = false;
    let mut tools = 0;
    for c in &cmds {
        let w = words(c);
        if let Some(tool) = w.first().filter(|t| t.starts_with("tools/")) {
            // A script of the repository's `tools/` (pictures and the like): checked with `bash -n` here,
            // run for real under `--ignored`.
            if !Path::new(env!("CARGO_MANIFEST_DIR")).join(tool).is_file() {
                return Err(format!("`{tool}` is not a file of the repository"));
            }
            long = true;
            tools += 1;
        } else if let Some(args) = skintight_args(c) {
            let quick = match args.first().map(String::as_str) {
                Some("mesh") | Some("body") => true,
                Some("simulate") => args.get(1).is_some_and(|scene| {
                    QUICK_SCENES
                        .iter()
                        .any(|q| *scene == format!("examples/{q}.json"))
                }),
                Some("design") => false,
                other => {
                    return Err(format!(
                        "`skintight {other:?}` is not a known subcommand here"
                    ));
                }
            };
            long |= !quick;
        } else if !(matches!(
            w.as_slice(),
            ["cargo", "build"]
                | ["cargo", "build", "--release"]
                | ["done"]
                | ["mkdir", ..]
                | ["ls", ..]
        ) || (w.first() == Some(&"for") && c.ends_with("; do")))
        {
            return Err(format!(
                "the command `{c}` is not one docs_run knows how to run"
            ));
        }
    }
    if calls.is_empty() && tools == 0 {
        return Err("a command block without a skintight call".into());
    }
    Ok(ShellKind::Cli { long })
}

// ---------------------------------------------------------------------------------------------------------
// Running shell blocks.

/// A temporary folder mirroring the repository: `repo/` holds links to the checkout's entries (its own `out/`),
/// `shared` links to `../shared`, `tmp/` stands for `/tmp/`.
struct Sandbox {
    _dir: tempfile::TempDir,
    root: PathBuf,
}

impl Sandbox {
    fn new() -> Sandbox {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().to_path_buf();
        let mirror = root.join("repo");
        std::fs::create_dir_all(&mirror).unwrap();
        for e in std::fs::read_dir(repo()).unwrap() {
            let e = e.unwrap();
            let name = e.file_name();
            if name == "out" || name == "target" || name == ".git" {
                continue;
            }
            std::os::unix::fs::symlink(e.path(), mirror.join(&name)).unwrap();
        }
        std::os::unix::fs::symlink(shared(), root.join("shared")).unwrap();
        std::fs::create_dir_all(root.join("tmp")).unwrap();
        std::fs::create_dir_all(root.join("missing")).unwrap();
        Sandbox { _dir: dir, root }
    }
    fn cwd(&self) -> PathBuf {
        self.root.join("repo")
    }
    fn tmp(&self) -> PathBuf {
        self.root.join("tmp")
    }
}

#[derive(Clone, Copy, PartialEq)]
enum Mode {
    /// Every call runs as written.
    Real,
    /// Every `skintight` call runs with its input replaced by a missing file and must exit 2 naming it.
    Syntax,
}

const PREAMBLE: &str = r#"
cargo() {
  case "$*" in
    build|"build --release") return 0 ;;
  esac
  if [ "$1" = run ]; then
    shift
    if [ "$1" = --release ]; then shift; fi
    if [ "$1" = -- ]; then shift; fi
    skintight "$@"
  else
    echo "docs_run: \`cargo $*\` is not run by this test" >&2
    return 97
  fi
}
"#;

const REAL: &str = r#"
skintight() { "$SKINTIGHT_BIN" "$@"; }
docs_tool() { bash "$@"; }
"#;

const SYNTAX: &str = r#"
docs_tool() { bash -n "$1"; }
skintight() {
  local args=("$@") n=1 i
  case "$1" in mesh|body) n=2 ;; esac
  for ((i = n; i < ${#args[@]}; i++)); do
    case "${args[i]}" in -*) ;; *) break ;; esac
  done
  local missing="$DOCS_MISSING/$(basename "${args[i]}")"
  args[i]="$missing"
  local rc=0
  "$SKINTIGHT_BIN" "${args[@]}" 2>"$DOCS_MISSING.err" >/dev/null || rc=$?
  if [ "$rc" -ne 2 ] || ! grep -qF "$missing" "$DOCS_MISSING.err" || grep -q 'Usage:' "$DOCS_MISSING.err"; then
    echo "docs_run: \`skintight $*\` with a missing input exited $rc (want 2, naming $missing): $(cat "$DOCS_MISSING.err")" >&2
    return 1
  fi
}
"#;

/// The block's text as the sandbox runs it: `./target/*/skintight` → `skintight`, `/tmp/` → the sandbox's,
/// `localhost:8080` → the test server.
fn rewrite(text: &str, sandbox: &Sandbox, port: Option<u16>) -> String {
    let mut t = text
        .lines()
        .map(|l| {
            if l.trim_start().starts_with("tools/") {
                format!("docs_tool {}", l.trim_start())
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
        .replace("./target/release/skintight", "skintight")
        .replace("./target/debug/skintight", "skintight")
        .replace("/tmp/", &format!("{}/", sandbox.tmp().display()));
    if let Some(port) = port {
        t = t.replace("localhost:8080", &format!("127.0.0.1:{port}"));
    }
    t
}

/// Shell variables a block assigns (`NAME=…` at the start of a line), carried to the next block.
fn assigned_variables(text: &str) -> BTreeSet<String> {
    text.lines()
        .filter_map(|l| {
            let (k, _) = l.trim_start().split_once('=')?;
            (!k.is_empty() && k.chars().all(|c| c.is_ascii_uppercase() || c == '_'))
                .then(|| k.to_string())
        })
        .collect()
}

fn script(sandbox: &Sandbox, mode: Mode, port: Option<u16>, text: &str) -> String {
    let state = sandbox.root.join("state.sh");
    let mut s = String::from(PREAMBLE);
    s.push_str(if mode == Mode::Real { REAL } else { SYNTAX });
    s.push_str(&format!(
        "[ -f '{0}' ] && source '{0}'\nset -eo pipefail\n",
        state.display()
    ));
    s.push_str(&rewrite(text, sandbox, port));
    s.push('\n');
    for v in assigned_variables(text) {
        s.push_str(&format!(
            "declare -p {v} >> '{}' 2>/dev/null || true\n",
            state.display()
        ));
    }
    s
}

struct Ran {
    status: Option<i32>,
    stdout: String,
    stderr: String,
}

fn bash(sandbox: &Sandbox, mode: Mode, port: Option<u16>, text: &str, limit: Duration) -> Ran {
    let out = Command::new("timeout")
        .args(["-k", "10", &limit.as_secs().to_string(), "bash", "-c"])
        .arg(script(sandbox, mode, port, text))
        .current_dir(sandbox.cwd())
        .env("SKINTIGHT_BIN", env!("CARGO_BIN_EXE_skintight"))
        .env("DOCS_MISSING", sandbox.root.join("missing"))
        .env("TMPDIR", sandbox.tmp())
        .stdin(Stdio::null())
        .output()
        .expect("bash runs");
    Ran {
        status: out.status.code(),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

fn expect_success(b: &Block, ran: &Ran) {
    assert_eq!(
        ran.status,
        Some(0),
        "{}: the block failed (exit {:?}; 124 = ran past the test's time limit)\n--- block\n{}\n--- stdout\n{}\n--- stderr\n{}",
        b.at(),
        ran.status,
        b.text,
        tail(&ran.stdout),
        tail(&ran.stderr)
    );
}

fn tail(s: &str) -> &str {
    let mut k = s.len().saturating_sub(4000);
    while !s.is_char_boundary(k) {
        k += 1;
    }
    &s[k..]
}

// ---------------------------------------------------------------------------------------------------------
// JSON blocks.

/// A copy of a scene or design job whose relative mesh paths are absolute, resolved against the repository
/// root or `examples/` (the first where the file exists).
fn resolve_paths(b: &Block, v: &mut Value) {
    match v {
        Value::Object(map) => {
            for (k, x) in map.iter_mut() {
                if k == "path"
                    && let Value::String(p) = x
                    && Path::new(p.as_str()).is_relative()
                {
                    let found = [repo().to_path_buf(), repo().join("examples")]
                        .iter()
                        .map(|base| base.join(p.as_str()))
                        .find(|c| c.exists())
                        .unwrap_or_else(|| {
                            panic!(
                                "{}: path {p:?} exists neither under the repository root nor under examples/",
                                b.at()
                            )
                        });
                    *x = Value::String(found.display().to_string());
                } else {
                    resolve_paths(b, x);
                }
            }
        }
        Value::Array(a) => a.iter_mut().for_each(|x| resolve_paths(b, x)),
        _ => {}
    }
}

/// The `examples/NAME.json` a block's heading names, if exactly one.
fn named_example(b: &Block) -> Option<String> {
    let mut names = BTreeSet::new();
    let mut rest = b.heading.as_str();
    while let Some(k) = rest.find("examples/") {
        rest = &rest[k + "examples/".len()..];
        let end = rest
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == '.'))
            .unwrap_or(rest.len());
        if let Some(name) = rest[..end].strip_suffix(".json") {
            names.insert(name.to_string());
        }
    }
    (names.len() == 1).then(|| names.into_iter().next().unwrap())
}

#[derive(Debug, PartialEq)]
enum JsonKind {
    Fragment,
    Scene { procedural: bool },
    DesignJob,
    ErrorEnvelope,
}

/// Checks a JSON block against what the code accepts and says what it is.
fn check_json(b: &Block) -> Result<JsonKind, String> {
    let v: Value = serde_json::from_str(&b.text).map_err(|e| format!("not valid JSON: {e}"))?;
    if b.marker.as_deref() == Some("<!-- fragment -->") {
        return Ok(JsonKind::Fragment);
    }
    let obj = v.as_object().ok_or("a JSON block that is not an object")?;
    let mut resolved = v.clone();
    resolve_paths(b, &mut resolved);
    let text = resolved.to_string();
    let kind = if obj.contains_key("bodies") {
        let bodies = skintight::design::batch_from_json(&text)
            .map_err(|e| format!("graded order: `{}`: {}", e.key, e.message))?
            .ok_or("a graded order without bodies")?;
        if let Some(name) = named_example(b) {
            let mut example: Value = serde_json::from_str(
                &std::fs::read_to_string(repo().join("examples").join(format!("{name}.json")))
                    .unwrap(),
            )
            .unwrap();
            resolve_paths(b, &mut example);
            if skintight::design::batch_from_json(&example.to_string()).unwrap() != Some(bodies) {
                return Err(format!(
                    "the block is not examples/{name}.json, which its text names"
                ));
            }
        }
        JsonKind::DesignJob
    } else if obj.contains_key("objectives") {
        let job = DesignJob::from_json(&text)
            .map_err(|e| format!("design job: `{}`: {}", e.key, e.message))?;
        if let Some(name) = named_example(b) {
            let file = repo().join("examples").join(format!("{name}.json"));
            let mut example: Value =
                serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
            resolve_paths(b, &mut example);
            let example = DesignJob::from_json(&example.to_string()).unwrap();
            if job != example {
                return Err(format!(
                    "the block is not examples/{name}.json, which its text names"
                ));
            }
        }
        JsonKind::DesignJob
    } else if obj.contains_key("body") && obj.contains_key("garment") {
        let scene =
            Scene::from_json(&text).map_err(|e| format!("scene: `{}`: {}", e.key, e.message))?;
        if let Some(name) = named_example(b) {
            let example = Scene::from_file(&repo().join("examples").join(format!("{name}.json")));
            let mut e: Value =
                serde_json::from_str(&example.map(|s| s.to_json()).unwrap()).unwrap();
            resolve_paths(b, &mut e);
            if Scene::from_json(&e.to_string()).unwrap() != scene {
                return Err(format!(
                    "the block is not examples/{name}.json, which its text names"
                ));
            }
        }
        let kind = v["body"]["source"]["kind"].as_str().unwrap_or("");
        JsonKind::Scene {
            procedural: kind == "cylinder" || kind == "sphere",
        }
    } else if let Some(e) = obj.get("error") {
        for k in ["code", "field", "message"] {
            if e.get(k).is_none() {
                return Err(format!("an error envelope without `error.{k}`"));
            }
        }
        JsonKind::ErrorEnvelope
    } else {
        return Err(
            "a JSON block that is neither a scene, a design job nor an error envelope; mark a deliberate \
             part with `<!-- fragment -->` on the line before it"
                .into(),
        );
    };
    Ok(kind)
}

/// Simulates a scene block with the binary under test.
fn simulate_scene_block(b: &Block, limit: Duration) {
    let sandbox = Sandbox::new();
    let mut v: Value = serde_json::from_str(&b.text).unwrap();
    resolve_paths(b, &mut v);
    let scene = sandbox.tmp().join("scene.json");
    std::fs::write(&scene, v.to_string()).unwrap();
    // `/tmp/` is the sandbox's (see `rewrite`).
    let text = "skintight simulate /tmp/scene.json --out /tmp/out --quiet";
    let ran = bash(&sandbox, Mode::Real, None, text, limit);
    if b.marker.as_deref() == Some("<!-- not admissible -->") {
        // The text says this garment is beyond its fabric's limits: it must end so, loudly (exit 4).
        let last = ran.stderr.lines().last().unwrap_or("");
        assert!(
            ran.status == Some(4) && last.starts_with("simulate: NOT ADMISSIBLE"),
            "{}: the block is marked not admissible but ended with exit {:?}: {last}",
            b.at(),
            ran.status
        );
    } else {
        expect_success(b, &ran);
    }
}

// ---------------------------------------------------------------------------------------------------------
// The service.

/// The server a document's `skintight serve` block starts, on a free loopback port; stopped when dropped.
struct Server {
    child: Child,
    port: u16,
    log: PathBuf,
}

impl Drop for Server {
    fn drop(&mut self) {
        let group = format!("-{}", self.child.id());
        let _ = Command::new("kill").args(["-TERM", "--", &group]).status();
        let deadline = Instant::now() + Duration::from_secs(10);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = Command::new("kill").args(["-KILL", "--", &group]).status();
        let _ = self.child.wait();
    }
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn start_server(b: &Block, sandbox: &Sandbox) -> Server {
    use std::os::unix::process::CommandExt;
    let port = free_port();
    let log = sandbox.root.join(format!("serve-{}.log", b.line));
    let file = std::fs::File::create(&log).unwrap();
    let child = Command::new("bash")
        .arg("-c")
        .arg(script(sandbox, Mode::Real, Some(port), &b.text))
        .current_dir(sandbox.cwd())
        .env("SKINTIGHT_BIN", env!("CARGO_BIN_EXE_skintight"))
        .env("SKINTIGHT_BIND", format!("127.0.0.1:{port}"))
        .env("SKINTIGHT_LOG_FILTER", "warn")
        .env("TMPDIR", sandbox.tmp())
        .env_remove("RUST_LOG")
        .stdin(Stdio::null())
        .stdout(file.try_clone().unwrap())
        .stderr(file)
        .process_group(0)
        .spawn()
        .expect("bash runs");
    let mut server = Server { child, port, log };
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let ok = Command::new("curl")
            .args([
                "-sf",
                "-o",
                "/dev/null",
                &format!("http://127.0.0.1:{port}/readyz"),
            ])
            .status()
            .is_ok_and(|s| s.success());
        if ok {
            return server;
        }
        if let Ok(Some(status)) = server.child.try_wait() {
            panic!(
                "{}: the server block exited ({status}) before it was ready; log:\n{}",
                b.at(),
                std::fs::read_to_string(&server.log).unwrap_or_default()
            );
        }
        assert!(
            Instant::now() < deadline,
            "{}: the server was not ready within a minute; log:\n{}",
            b.at(),
            std::fs::read_to_string(&server.log).unwrap_or_default()
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// What a block's `#` comment lines promise its output holds: JSON keys (`"key":`) and SSE event names.
fn promised(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for l in text.lines() {
        let Some(c) = l.trim_start().strip_prefix('#') else {
            continue;
        };
        let c = c.trim();
        if let Some(event) = c.strip_prefix("event: ") {
            out.push(format!("event: {}", event.trim()));
        }
        let mut rest = c;
        while let Some(k) = rest.find('"') {
            rest = &rest[k + 1..];
            let Some(end) = rest.find('"') else { break };
            let word = &rest[..end];
            rest = &rest[end + 1..];
            if rest.starts_with(':') {
                out.push(format!("\"{word}\":"));
            }
        }
    }
    out
}

/// Runs a document's service blocks against its server, in order; returns the sandbox and server for checks.
fn run_service(doc: &str, all: &[Block]) -> (Sandbox, Server) {
    let ours: Vec<&Block> = all
        .iter()
        .filter(|b| b.file == doc && b.lang != "json")
        .collect();
    let server_block = ours
        .iter()
        .find(|b| shell_kind(b) == Ok(ShellKind::Server))
        .unwrap_or_else(|| panic!("{doc} has curl blocks but no `skintight serve` block"));
    let sandbox = Sandbox::new();
    let server = start_server(server_block, &sandbox);
    for b in ours
        .iter()
        .filter(|b| shell_kind(b) == Ok(ShellKind::Service))
    {
        let ran = bash(
            &sandbox,
            Mode::Real,
            Some(server.port),
            &b.text,
            Duration::from_secs(300),
        );
        expect_success(b, &ran);
        for p in promised(&b.text) {
            assert!(
                ran.stdout.contains(&p),
                "{}: the output lacks {p}, which the block's comment shows\n--- stdout\n{}\n--- server log\n{}",
                b.at(),
                tail(&ran.stdout),
                std::fs::read_to_string(&server.log).unwrap_or_default()
            );
        }
        let shows_error = b
            .text
            .lines()
            .any(|l| l.trim_start().starts_with('#') && l.contains("\"error\""));
        assert!(
            shows_error || !ran.stdout.contains("{\"error\":"),
            "{}: the server answered with an error\n--- stdout\n{}",
            b.at(),
            tail(&ran.stdout)
        );
        // A job submitted by a block that the document does not follow (it assigns no JOB) is not part of
        // the walk-through; cancel it so it does not hold a worker.
        if b.text.contains("/v1/jobs")
            && b.text.contains("-X POST")
            && !assigned_variables(&b.text).contains("JOB")
        {
            for line in ran.stdout.lines() {
                if let Ok(v) = serde_json::from_str::<Value>(line)
                    && v["status"] == "queued"
                    && let Some(id) = v["id"].as_str()
                {
                    let _ = Command::new("curl")
                        .args([
                            "-s",
                            "-X",
                            "POST",
                            &format!("http://127.0.0.1:{}/v1/jobs/{id}/cancel", server.port),
                        ])
                        .output();
                }
            }
        }
    }
    (sandbox, server)
}

fn get_json(server: &Server, path: &str) -> Value {
    let out = Command::new("curl")
        .args(["-s", &format!("http://127.0.0.1:{}{path}", server.port)])
        .output()
        .unwrap();
    serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("GET {path}: {e}: {}", String::from_utf8_lossy(&out.stdout)))
}

/// The value a shell variable ended with in the service blocks' carried state.
fn carried(sandbox: &Sandbox, name: &str) -> String {
    let out = Command::new("bash")
        .arg("-c")
        .arg(format!(
            "source '{}'; printf %s \"${name}\"",
            sandbox.root.join("state.sh").display()
        ))
        .output()
        .unwrap();
    String::from_utf8(out.stdout).unwrap()
}

// ---------------------------------------------------------------------------------------------------------
// The tests.

#[test]
fn every_block_is_recognized() {
    let all = blocks();
    assert!(all.len() >= 20, "only {} blocks found", all.len());
    let mut unknown = Vec::new();
    for b in &all {
        let known = match b.lang.as_str() {
            "json" => check_json(b).map(|_| ()),
            "sh" | "bash" | "shell" | "console" => shell_kind(b).map(|_| ()),
            // A figure (docs/ARCHITECTURE.md's diagram): nothing to run.
            "text" => Ok(()),
            other => Err(format!(
                "a block of language {other:?}: docs_run runs json and shell blocks (and takes text figures)"
            )),
        };
        if let Err(e) = known {
            unknown.push(format!("{}: {e}", b.at()));
        }
    }
    assert!(
        unknown.is_empty(),
        "blocks the test does not accept:\n{}",
        unknown.join("\n")
    );
}

#[test]
fn json_blocks_on_procedural_bodies_simulate() {
    let mut ran = 0;
    for b in blocks().iter().filter(|b| b.lang == "json") {
        if check_json(b) == Ok(JsonKind::Scene { procedural: true }) {
            simulate_scene_block(b, Duration::from_secs(300));
            ran += 1;
        }
    }
    assert!(ran >= 1, "no scene on a procedural body in the docs");
}

#[test]
fn quick_command_blocks_run_and_long_ones_parse() {
    let mut quick = 0;
    for b in blocks().iter().filter(|b| b.lang != "json") {
        let Ok(ShellKind::Cli { long }) = shell_kind(b) else {
            continue;
        };
        let sandbox = Sandbox::new();
        let mode = if long { Mode::Syntax } else { Mode::Real };
        let ran = bash(&sandbox, mode, None, &b.text, Duration::from_secs(300));
        expect_success(b, &ran);
        quick += usize::from(!long);
    }
    assert!(quick >= 1, "no quick command block ran for real");
}

#[test]
fn the_suite_block_is_what_ci_runs() {
    let ci = std::fs::read_to_string(repo().join(".ci/run")).unwrap();
    for b in blocks().iter().filter(|b| b.lang != "json") {
        if shell_kind(b) == Ok(ShellKind::Suite) {
            assert!(
                ci.lines().any(|l| l.trim() == b.text.trim()),
                "{}: `{}` is not the command .ci/run runs",
                b.at(),
                b.text.trim()
            );
        }
    }
}

#[test]
fn docker_blocks_match_the_dockerfile() {
    for b in blocks().iter().filter(|b| b.lang != "json") {
        if shell_kind(b) != Ok(ShellKind::Docker) {
            continue;
        }
        let cmds = commands(&b.text);
        let build = cmds
            .iter()
            .find(|c| c.starts_with("docker build"))
            .unwrap_or_else(|| panic!("{}: no docker build", b.at()));
        let w = words(build);
        let file = w[w.iter().position(|x| *x == "-f").expect("-f FILE") + 1];
        let tag = w[w.iter().position(|x| *x == "-t").expect("-t TAG") + 1];
        let dockerfile = std::fs::read_to_string(repo().join(file))
            .unwrap_or_else(|e| panic!("{}: {file}: {e}", b.at()));
        if let Some(run) = cmds.iter().find(|c| c.starts_with("docker run")) {
            assert_eq!(
                words(run).last(),
                Some(&tag),
                "{}: runs another image than it builds",
                b.at()
            );
            for w in words(run) {
                if let Some((_, inside)) = w.split_once(':')
                    && inside.starts_with('/')
                {
                    let inside = inside.trim_end_matches(":ro");
                    let dir = Path::new(inside).parent().unwrap().to_str().unwrap();
                    assert!(
                        dockerfile.contains(inside) || dockerfile.contains(dir),
                        "{}: {file} does not mention {inside}",
                        b.at()
                    );
                }
            }
        }
    }
}

#[test]
fn readme_service_walkthrough_runs() {
    let all = blocks();
    let (sandbox, server) = run_service("README.md", &all);
    let job = carried(&sandbox, "JOB");
    assert!(!job.is_empty(), "the walk-through set no JOB");
    let j = get_json(&server, &format!("/v1/jobs/{job}"));
    assert_eq!(j["status"], "completed", "{j}");
    let out = sandbox.cwd().join("out/calf");
    let result: Value =
        serde_json::from_slice(&std::fs::read(out.join("result.json")).unwrap()).unwrap();
    assert_eq!(result["converged"], true, "{result}");
    for glb in ["garment.glb", "body.glb"] {
        assert!(
            std::fs::read(out.join(glb)).unwrap().starts_with(b"glTF"),
            "{glb}"
        );
    }
    assert!(
        std::fs::read_to_string(out.join("patterns.svg"))
            .unwrap()
            .contains("<svg")
    );
}

#[test]
fn api_service_walkthrough_runs() {
    let all = blocks();
    let (sandbox, server) = run_service("docs/API.md", &all);
    let job = carried(&sandbox, "JOB");
    let j = get_json(&server, &format!("/v1/jobs/{job}"));
    assert_eq!(j["status"], "completed", "{j}");
    assert!(sandbox.cwd().join("trace.csv").is_file());
}

/// Every long block for real: designs of minutes, the pants, the docker build (when docker runs).
/// `DOCS_RUN_BLOCK=FILE:LINE` runs only that block.
#[test]
#[ignore = "minutes to hours: designs and the pants run for real"]
fn long_blocks_run_for_real() {
    let only = std::env::var("DOCS_RUN_BLOCK").ok();
    let limit = Duration::from_secs(4 * 3600);
    let mut ran = 0;
    for b in blocks() {
        if only.as_ref().is_some_and(|o| *o != b.at()) {
            continue;
        }
        if b.lang == "json" {
            match check_json(&b) {
                Ok(JsonKind::Scene { procedural: false }) => simulate_scene_block(&b, limit),
                Ok(JsonKind::DesignJob) => {
                    let sandbox = Sandbox::new();
                    let mut v: Value = serde_json::from_str(&b.text).unwrap();
                    resolve_paths(&b, &mut v);
                    let job = sandbox.tmp().join("job.json");
                    std::fs::write(&job, v.to_string()).unwrap();
                    let text = "skintight design /tmp/job.json --out /tmp/out --quiet";
                    expect_success(&b, &bash(&sandbox, Mode::Real, None, text, limit));
                }
                _ => continue,
            }
            ran += 1;
            continue;
        }
        match shell_kind(&b) {
            Ok(ShellKind::Cli { long: true }) => {
                let sandbox = Sandbox::new();
                let text = b
                    .text
                    .replace("examples/X", &format!("examples/{EXAMPLE_PLACEHOLDER}"))
                    .replace("/tmp/X", &format!("/tmp/{EXAMPLE_PLACEHOLDER}"));
                let r = bash(&sandbox, Mode::Real, None, &text, limit);
                // Exit 3: not converged within the limits, results written — a run, not a broken block.
                if r.status != Some(3) {
                    expect_success(&b, &r);
                }
                ran += 1;
            }
            Ok(ShellKind::Docker) => {
                let docker = Command::new("docker").arg("info").output();
                if !docker.is_ok_and(|o| o.status.success()) {
                    eprintln!("{}: docker does not run here; skipped", b.at());
                    continue;
                }
                let build = commands(&b.text)
                    .into_iter()
                    .find(|c| c.starts_with("docker build"))
                    .unwrap();
                let status = Command::new("bash")
                    .arg("-c")
                    .arg(&build)
                    .current_dir(repo())
                    .status()
                    .unwrap();
                assert!(status.success(), "{}: {build}", b.at());
                ran += 1;
            }
            _ => {}
        }
    }
    assert!(ran >= 1 || only.is_some(), "no long block found");
}

#[test]
fn unusable_input_exit_status_is_two() {
    // The syntax check of long blocks leans on this: a missing input is exit 2 naming the file.
    let missing = std::env::temp_dir().join("docs_run_no_such_scene.json");
    let out = Command::new(env!("CARGO_BIN_EXE_skintight"))
        .arg("simulate")
        .arg(&missing)
        .args(["--out", "/nonexistent-docs-run"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(UNUSABLE_INPUT));
    assert!(String::from_utf8_lossy(&out.stderr).contains(&*missing.to_string_lossy()));
}

#[path = "docs_support/citations.rs"]
mod citations;

#[test]
fn cited_code_exists() {
    let sources = citations::workspace_sources(repo());
    assert!(
        sources.len() > 100,
        "only {} Rust files found",
        sources.len()
    );
    let mut missing = Vec::new();
    for doc in citations::checked_documents(repo()) {
        let text = std::fs::read_to_string(&doc).expect("a checked document");
        let name = doc
            .strip_prefix(repo())
            .unwrap_or(&doc)
            .display()
            .to_string();
        missing.extend(citations::missing(&name, &text, &sources));
    }
    assert!(
        missing.is_empty(),
        "the docs cite code that does not exist:\n{}",
        missing.join("\n")
    );
}
