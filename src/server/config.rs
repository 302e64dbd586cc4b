//! Configuration of the HTTP service.
//!
//! Three layers, later ones winning key by key: the built-in `config/default.toml` (compiled into the binary),
//! an optional file given with `--config FILE` (it names only the keys it changes), and environment variables
//! `SKINTIGHT_…` listed in [`ENV_OVERRIDES`].

use std::net::SocketAddr;
use std::path::{Path, PathBuf};

use serde::Deserialize;

/// The built-in defaults.
pub const DEFAULT_TOML: &str = include_str!("../../config/default.toml");

/// Environment variables that override single keys: (variable, section, key, kind).
pub const ENV_OVERRIDES: &[(&str, &str, &str, EnvKind)] = &[
    ("SKINTIGHT_BIND", "server", "bind", EnvKind::Str),
    (
        "SKINTIGHT_REQUEST_TIMEOUT_S",
        "server",
        "request_timeout_s",
        EnvKind::Int,
    ),
    (
        "SKINTIGHT_HEADER_TIMEOUT_S",
        "server",
        "header_timeout_s",
        EnvKind::Int,
    ),
    (
        "SKINTIGHT_MAX_ASSET_BYTES",
        "server",
        "max_asset_bytes",
        EnvKind::Int,
    ),
    (
        "SKINTIGHT_SERVER_MAX_MEMORY_BYTES",
        "server",
        "max_memory_bytes",
        EnvKind::Int,
    ),
    ("SKINTIGHT_DATABASE", "database", "path", EnvKind::Str),
    ("SKINTIGHT_DATABASE_URL", "database", "url", EnvKind::Str),
    ("SKINTIGHT_LEASE_S", "jobs", "lease_s", EnvKind::Int),
    ("SKINTIGHT_WORKERS", "jobs", "workers", EnvKind::Int),
    (
        "SKINTIGHT_WORKER_OPS_ADDR",
        "worker",
        "ops_addr",
        EnvKind::Str,
    ),
    (
        "SKINTIGHT_JOB_TIME_LIMIT_S",
        "jobs",
        "time_limit_s",
        EnvKind::Int,
    ),
    (
        "SKINTIGHT_MAX_ATTEMPTS",
        "jobs",
        "max_attempts",
        EnvKind::Int,
    ),
    (
        "SKINTIGHT_MAX_MEMORY_BYTES",
        "jobs",
        "max_memory_bytes",
        EnvKind::Int,
    ),
    ("SKINTIGHT_JOB_ISOLATION", "jobs", "isolation", EnvKind::Str),
    ("SKINTIGHT_YARNS_DIR", "jobs", "yarns_dir", EnvKind::Str),
    (
        "SKINTIGHT_ENABLE_SELFTEST",
        "jobs",
        "enable_selftest",
        EnvKind::Bool,
    ),
    ("SKINTIGHT_AUTH_DISABLED", "auth", "disabled", EnvKind::Bool),
    (
        "SKINTIGHT_OPERATOR_KEY",
        "auth",
        "operator_keys",
        EnvKind::StrList,
    ),
    ("SKINTIGHT_LOG_FORMAT", "log", "format", EnvKind::Str),
    ("SKINTIGHT_LOG_FILTER", "log", "filter", EnvKind::Str),
];

/// How an environment variable's text becomes a TOML value.
#[derive(Debug, Clone, Copy)]
pub enum EnvKind {
    Str,
    Int,
    Bool,
    /// Comma-separated list of strings.
    StrList,
}

/// The whole configuration.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    pub server: ServerConfig,
    pub database: DatabaseConfig,
    pub jobs: JobsConfig,
    pub auth: AuthConfig,
    pub log: LogConfig,
    pub worker: WorkerConfig,
}

/// Settings of a worker node (`skintight worker`) only.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorkerConfig {
    /// The worker node's ops listener, `host:port`, serving only `/healthz`, `/readyz` and `/metrics`;
    /// empty: no port.
    pub ops_addr: String,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServerConfig {
    /// Listening address, `host:port`.
    pub bind: String,
    /// Time limit until the response head is sent, s.
    pub request_timeout_s: u64,
    /// Time limit for a connection to send a request's headers, s; a silent or partial connection is
    /// closed after it.
    pub header_timeout_s: u64,
    /// Most connections open at once; more wait in the listen backlog.
    pub max_connections: usize,
    /// Largest JSON request body, bytes.
    pub max_json_bytes: usize,
    /// Largest uploaded asset, bytes.
    pub max_asset_bytes: usize,
    /// The server process's own memory, bytes: what its reads of meshes may take is derived from it (see
    /// [`ServerConfig::asset_budget_bytes`]), and `/metrics` reports the process's resident memory beside it.
    pub max_memory_bytes: u64,
    /// The server-wide budget of the meshes read inside the server process (uploads checked on arrival,
    /// assets checked and costed at submission), bytes (see [`super::asset_budget`]); 0: half of
    /// `max_memory_bytes`. At most half of it (the rest is the allocator's slack after reads, the
    /// database's cache and the server itself).
    pub asset_check_memory_bytes: u64,
    /// How long a request waits for its share of that budget before it is answered 429, s.
    pub asset_check_wait_s: u64,
    /// CORS origins; empty = CORS off.
    pub cors_origins: Vec<String>,
    /// Graceful-shutdown wait for running jobs, s.
    pub shutdown_grace_s: u64,
}

impl ServerConfig {
    /// The byte budget of the meshes read inside the server: `asset_check_memory_bytes`, or half of
    /// `max_memory_bytes` when that is 0.
    pub fn asset_budget_bytes(&self) -> u64 {
        if self.asset_check_memory_bytes == 0 {
            self.max_memory_bytes / 2
        } else {
            self.asset_check_memory_bytes
        }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DatabaseConfig {
    /// SQLite file (when `url` is empty).
    pub path: PathBuf,
    /// A PostgreSQL connection URL (`postgres://user:password@host:port/database`); empty: SQLite at `path`.
    pub url: String,
}

impl DatabaseConfig {
    /// Whether the store is a PostgreSQL database.
    pub fn is_postgres(&self) -> bool {
        !self.url.is_empty()
    }

    /// The database named for people (logs, errors): the SQLite file, or the PostgreSQL URL without its
    /// password.
    pub fn display(&self) -> String {
        if self.url.is_empty() {
            return self.path.display().to_string();
        }
        match self.url.split_once("://") {
            Some((scheme, rest)) => match rest.rsplit_once('@') {
                Some((user, host)) => {
                    let user = user.split(':').next().unwrap_or("");
                    format!("{scheme}://{user}@{host}")
                }
                None => self.url.clone(),
            },
            None => self.url.clone(),
        }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JobsConfig {
    /// Worker threads; 0 = available parallelism.
    pub workers: usize,
    /// How long a worker's claim on a running job lasts unless renewed, s; workers renew it every third
    /// of it, and a job whose lease expired is re-queued and resumed by another worker.
    pub lease_s: u64,
    /// Time limit of one job run, s.
    pub time_limit_s: u64,
    /// Largest accepted job spec, bytes of JSON.
    pub max_spec_bytes: usize,
    /// Register the built-in `selftest` kind (operator smoke test).
    pub enable_selftest: bool,
    /// Folder of the shared yarn patterns named by `yarn_simulate` jobs.
    pub yarns_dir: PathBuf,
    /// Runs of one job before it fails with `crashed_repeatedly` (a run that never ended, e.g. the server
    /// died during it, counts).
    pub max_attempts: u32,
    /// Admission limits on a job's estimated size (see [`crate::scene::Estimate`]).
    pub max_cloth_triangles: u64,
    pub max_boundary_samples: u64,
    pub max_body_tets: u64,
    pub max_unknowns: u64,
    /// Estimated peak memory of one job, bytes (admission).
    pub max_estimated_memory_bytes: u64,
    /// Newton iterations of one job in all (every equilibrium of a design).
    pub max_newton_iterations: u64,
    /// How jobs of the built-in kinds run: `"process"` (each in a child process of the server, under the
    /// limits below) or `"thread"` (on a blocking thread of the server process).
    pub isolation: String,
    /// The executable of job processes; empty: this server's own executable.
    pub runner: String,
    /// Address-space limit of a job process, bytes (`RLIMIT_AS`).
    pub max_memory_bytes: u64,
    /// Refuse at admission a job whose estimated memory exceeds `max_memory_bytes` (with process
    /// isolation); off only to see such a job fail `out_of_memory` (tests of the isolation).
    pub admit_within_memory_limit: bool,
    /// CPU-time limit of a job process, s (`RLIMIT_CPU`, all its threads together).
    pub max_cpu_s: u64,
}

impl JobsConfig {
    /// The admission limits of jobs.
    pub fn limits(&self) -> crate::scene::Limits {
        crate::scene::Limits {
            max_cloth_triangles: self.max_cloth_triangles,
            max_boundary_samples: self.max_boundary_samples,
            max_body_tets: self.max_body_tets,
            max_unknowns: self.max_unknowns,
            max_estimated_memory_bytes: self.max_estimated_memory_bytes,
            max_newton_iterations: self.max_newton_iterations,
            max_process_memory_bytes: if self.isolation == "process"
                && self.admit_within_memory_limit
            {
                self.max_memory_bytes
            } else {
                u64::MAX
            },
        }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AuthConfig {
    pub disabled: bool,
    pub operator_keys: Vec<String>,
    pub keys: Vec<ApiKey>,
}

/// One bearer token and the tenant it acts for.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ApiKey {
    pub key: String,
    pub tenant: String,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LogConfig {
    /// "text" or "json".
    pub format: String,
    /// EnvFilter directives.
    pub filter: String,
}

/// A configuration that cannot be used; the message names the file, variable or key.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read config file {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("config {origin} is not valid TOML: {message}")]
    Parse { origin: String, message: String },
    #[error("environment variable {var}: {message}")]
    Env { var: String, message: String },
    #[error("config key {key}: {message}")]
    Invalid { key: String, message: String },
}

impl Config {
    /// The built-in defaults, `file` on top (if any), then the process environment.
    pub fn load(file: Option<&Path>) -> Result<Config, ConfigError> {
        Config::load_with_env(file, |name| std::env::var(name).ok())
    }

    /// Like [`Config::load`] with a given environment lookup (for tests).
    pub fn load_with_env(
        file: Option<&Path>,
        env: impl Fn(&str) -> Option<String>,
    ) -> Result<Config, ConfigError> {
        let mut merged = parse_table(DEFAULT_TOML, "config/default.toml")?;
        if let Some(path) = file {
            let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
                path: path.to_path_buf(),
                source,
            })?;
            let overlay = parse_table(&text, &path.display().to_string())?;
            merge(&mut merged, overlay);
        }
        for &(var, section, key, kind) in ENV_OVERRIDES {
            let Some(raw) = env(var) else { continue };
            let value = env_value(&raw, kind).map_err(|message| ConfigError::Env {
                var: var.to_string(),
                message,
            })?;
            let table = merged
                .entry(section)
                .or_insert_with(|| toml::Value::Table(Default::default()));
            if let toml::Value::Table(t) = table {
                t.insert(key.to_string(), value);
            }
        }
        let config: Config =
            toml::Value::Table(merged)
                .try_into()
                .map_err(|e: toml::de::Error| ConfigError::Invalid {
                    key: "(config)".into(),
                    message: e.message().to_string(),
                })?;
        config.check()?;
        Ok(config)
    }

    /// Parses a complete configuration from TOML text layered over the defaults (for tests and embedding).
    pub fn from_toml_overlay(text: &str) -> Result<Config, ConfigError> {
        let mut merged = parse_table(DEFAULT_TOML, "config/default.toml")?;
        merge(&mut merged, parse_table(text, "(overlay)")?);
        let config: Config =
            toml::Value::Table(merged)
                .try_into()
                .map_err(|e: toml::de::Error| ConfigError::Invalid {
                    key: "(config)".into(),
                    message: e.message().to_string(),
                })?;
        config.check()?;
        Ok(config)
    }

    /// Checks relations between keys, including the rule that an unauthenticated server binds only to
    /// loopback addresses.
    pub fn check(&self) -> Result<(), ConfigError> {
        let addr = self.bind_addr()?;
        if let Some(ops) = self.ops_addr()?
            && self.auth.disabled
            && !ops.ip().is_loopback()
        {
            return Err(ConfigError::Invalid {
                key: "worker.ops_addr".into(),
                message: format!(
                    "{ops} is not a loopback address; without authentication (auth.disabled = true) \
                     the ops port binds only to 127.0.0.1 or [::1]"
                ),
            });
        }
        if self.auth.disabled && !addr.ip().is_loopback() {
            return Err(ConfigError::Invalid {
                key: "server.bind".into(),
                message: format!(
                    "{addr} is not a loopback address; without authentication (auth.disabled = true) \
                     the server binds only to 127.0.0.1 or [::1]"
                ),
            });
        }
        if !self.auth.disabled && self.auth.keys.is_empty() {
            return Err(ConfigError::Invalid {
                key: "auth.keys".into(),
                message:
                    "no API keys configured; add [[auth.keys]] entries or set auth.disabled = true \
                          (loopback only)"
                        .into(),
            });
        }
        for (i, k) in self.auth.keys.iter().enumerate() {
            if let Some((j, first)) = self.auth.keys[..i]
                .iter()
                .enumerate()
                .find(|(_, o)| o.key == k.key)
            {
                return Err(ConfigError::Invalid {
                    key: format!("auth.keys[{i}].key"),
                    message: format!(
                        "the same key as auth.keys[{j}]: tenant {:?} and tenant {:?} would share it (a key \
                         acts for one tenant); give each entry a key of its own",
                        first.tenant, k.tenant
                    ),
                });
            }
            if k.key.trim() != k.key || k.key.chars().any(|c| !c.is_ascii_graphic()) {
                return Err(ConfigError::Invalid {
                    key: format!("auth.keys[{i}].key"),
                    message: format!(
                        "the key of tenant {:?} has spaces or characters that are not visible ASCII, \
                         which a Bearer header cannot carry",
                        k.tenant
                    ),
                });
            }
            if k.key.len() < 8 {
                return Err(ConfigError::Invalid {
                    key: format!("auth.keys[{i}].key"),
                    message: "an API key must have at least 8 characters".into(),
                });
            }
            if k.tenant.is_empty() {
                return Err(ConfigError::Invalid {
                    key: format!("auth.keys[{i}].tenant"),
                    message: "the tenant must not be empty".into(),
                });
            }
        }
        if self.jobs.isolation != "process" && self.jobs.isolation != "thread" {
            return Err(ConfigError::Invalid {
                key: "jobs.isolation".into(),
                message: format!(
                    "{:?} is neither \"process\" nor \"thread\"",
                    self.jobs.isolation
                ),
            });
        }
        if self.database.is_postgres()
            && !(self.database.url.starts_with("postgres://")
                || self.database.url.starts_with("postgresql://"))
        {
            return Err(ConfigError::Invalid {
                key: "database.url".into(),
                message: format!(
                    "{:?} is not a PostgreSQL URL; write postgres://user:password@host:port/database, or \
                     leave it empty for SQLite at database.path",
                    self.database.display()
                ),
            });
        }
        if self.jobs.lease_s < 2 {
            return Err(ConfigError::Invalid {
                key: "jobs.lease_s".into(),
                message: "must be at least 2 (workers renew their leases every third of it)".into(),
            });
        }
        if self.log.format != "text" && self.log.format != "json" {
            return Err(ConfigError::Invalid {
                key: "log.format".into(),
                message: format!("{:?} is neither \"text\" nor \"json\"", self.log.format),
            });
        }
        use super::asset_budget::AssetBudget;
        let budget = self.server.asset_budget_bytes();
        if budget > self.server.max_memory_bytes / 2 {
            return Err(ConfigError::Invalid {
                key: "server.asset_check_memory_bytes".into(),
                message: format!(
                    "{budget} bytes is more than half of server.max_memory_bytes = {} bytes (the other half \
                     is the allocator's slack after reads, the database's cache and the server itself); \
                     raise server.max_memory_bytes to at least {}, or set this key to 0 (half of it)",
                    self.server.max_memory_bytes,
                    budget.saturating_mul(2),
                ),
            });
        }
        if AssetBudget::file_part(budget)
            < AssetBudget::file_charge(self.server.max_asset_bytes as u64)
        {
            let key = if self.server.asset_check_memory_bytes == 0 {
                "server.max_memory_bytes"
            } else {
                "server.asset_check_memory_bytes"
            };
            return Err(ConfigError::Invalid {
                key: key.into(),
                message: format!(
                    "the budget for reading meshes, {budget} bytes (server.asset_check_memory_bytes, or \
                     half of server.max_memory_bytes when that is 0), a quarter of which holds the files \
                     being read (3 copies each), cannot hold an upload of server.max_asset_bytes = {} \
                     bytes; raise it to at least 12 × that (server.max_memory_bytes to 24 ×), or lower \
                     server.max_asset_bytes",
                    self.server.max_asset_bytes,
                ),
            });
        }
        for (key, v) in [
            ("server.request_timeout_s", self.server.request_timeout_s),
            ("server.header_timeout_s", self.server.header_timeout_s),
            ("server.max_connections", self.server.max_connections as u64),
            ("server.max_memory_bytes", self.server.max_memory_bytes),
            ("jobs.time_limit_s", self.jobs.time_limit_s),
            ("jobs.max_attempts", u64::from(self.jobs.max_attempts)),
            ("jobs.max_cloth_triangles", self.jobs.max_cloth_triangles),
            ("jobs.max_boundary_samples", self.jobs.max_boundary_samples),
            ("jobs.max_body_tets", self.jobs.max_body_tets),
            ("jobs.max_unknowns", self.jobs.max_unknowns),
            (
                "jobs.max_estimated_memory_bytes",
                self.jobs.max_estimated_memory_bytes,
            ),
            ("jobs.max_memory_bytes", self.jobs.max_memory_bytes),
            ("jobs.max_cpu_s", self.jobs.max_cpu_s),
            (
                "jobs.max_newton_iterations",
                self.jobs.max_newton_iterations,
            ),
        ] {
            if v == 0 {
                return Err(ConfigError::Invalid {
                    key: key.into(),
                    message: "must be at least 1".into(),
                });
            }
        }
        Ok(())
    }

    /// The listening address.
    pub fn bind_addr(&self) -> Result<SocketAddr, ConfigError> {
        self.server.bind.parse().map_err(|e| ConfigError::Invalid {
            key: "server.bind".into(),
            message: format!(
                "{:?} is not an address like 127.0.0.1:8080: {e}",
                self.server.bind
            ),
        })
    }

    /// A worker node's ops listener (`worker.ops_addr`); `None` when empty.
    pub fn ops_addr(&self) -> Result<Option<SocketAddr>, ConfigError> {
        if self.worker.ops_addr.is_empty() {
            return Ok(None);
        }
        self.worker
            .ops_addr
            .parse()
            .map(Some)
            .map_err(|e| ConfigError::Invalid {
                key: "worker.ops_addr".into(),
                message: format!(
                    "{:?} is not an address like 127.0.0.1:9464: {e}",
                    self.worker.ops_addr
                ),
            })
    }

    /// The number of worker threads (resolving 0 to the available parallelism).
    pub fn worker_count(&self) -> usize {
        if self.jobs.workers > 0 {
            self.jobs.workers
        } else {
            std::thread::available_parallelism().map_or(1, |n| n.get())
        }
    }
}

fn parse_table(text: &str, origin: &str) -> Result<toml::Table, ConfigError> {
    text.parse::<toml::Table>().map_err(|e| ConfigError::Parse {
        origin: origin.to_string(),
        message: e.message().to_string(),
    })
}

/// Deep merge: tables merge key by key, everything else is replaced.
fn merge(base: &mut toml::Table, overlay: toml::Table) {
    for (k, v) in overlay {
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge(b, o),
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}

fn env_value(raw: &str, kind: EnvKind) -> Result<toml::Value, String> {
    Ok(match kind {
        EnvKind::Str => toml::Value::String(raw.to_string()),
        EnvKind::Int => toml::Value::Integer(
            raw.trim()
                .parse::<i64>()
                .ok()
                .filter(|v| *v >= 0)
                .ok_or_else(|| format!("{raw:?} is not a non-negative integer"))?,
        ),
        EnvKind::Bool => toml::Value::Boolean(match raw.trim() {
            "1" | "true" | "yes" => true,
            "0" | "false" | "no" => false,
            _ => return Err(format!("{raw:?} is not true/false")),
        }),
        EnvKind::StrList => toml::Value::Array(
            raw.split(',')
                .map(str::trim)
                .filter(|s| !s.is_empty())
                .map(|s| toml::Value::String(s.to_string()))
                .collect(),
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_need_keys_or_disabled_auth() {
        let err = Config::load_with_env(None, |_| None).unwrap_err();
        assert!(err.to_string().contains("auth.keys"), "{err}");
        let c = Config::load_with_env(None, |v| {
            (v == "SKINTIGHT_AUTH_DISABLED").then(|| "true".to_string())
        })
        .unwrap();
        assert_eq!(c.server.bind, "127.0.0.1:8080");
        assert!(!c.jobs.enable_selftest);
        assert!(c.server.cors_origins.is_empty());
    }

    #[test]
    fn env_overrides_file_overrides_defaults() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("c.toml");
        std::fs::write(
            &file,
            "[jobs]\nworkers = 3\n[auth]\ndisabled = true\n[database]\npath = \"/tmp/x.db\"\n",
        )
        .unwrap();
        let c = Config::load_with_env(Some(&file), |v| match v {
            "SKINTIGHT_WORKERS" => Some("5".into()),
            "SKINTIGHT_BIND" => Some("127.0.0.1:0".into()),
            _ => None,
        })
        .unwrap();
        assert_eq!(c.jobs.workers, 5);
        assert_eq!(c.worker_count(), 5);
        assert_eq!(c.server.bind, "127.0.0.1:0");
        assert_eq!(c.database.path, PathBuf::from("/tmp/x.db"));
        assert!(!c.database.is_postgres());
        // Keys the file does not name keep their defaults.
        assert_eq!(c.jobs.time_limit_s, 3600);
    }

    #[test]
    fn the_default_limits_are_the_cli_limits() {
        let c = Config::from_toml_overlay("[auth]\ndisabled = true\n").unwrap();
        // The same admission limits, and the job processes' memory limit on top.
        assert_eq!(
            c.jobs.limits(),
            crate::scene::Limits {
                max_process_memory_bytes: c.jobs.max_memory_bytes,
                ..crate::scene::Limits::default()
            }
        );
        assert_eq!(c.jobs.max_attempts, 3);
        assert!(c.server.header_timeout_s >= 1);
        let err = Config::from_toml_overlay("[auth]\ndisabled = true\n[jobs]\nmax_unknowns = 0\n")
            .unwrap_err();
        assert!(err.to_string().contains("jobs.max_unknowns"), "{err}");
    }

    #[test]
    fn worker_ops_addr_is_optional_checked_and_loopback_without_auth() {
        let open = |v: &str| match v {
            "SKINTIGHT_AUTH_DISABLED" => Some("true".to_string()),
            _ => None,
        };
        assert_eq!(
            Config::load_with_env(None, open)
                .unwrap()
                .ops_addr()
                .unwrap(),
            None
        );
        let c = Config::load_with_env(None, |v| match v {
            "SKINTIGHT_WORKER_OPS_ADDR" => Some("127.0.0.1:9464".into()),
            other => open(other),
        })
        .unwrap();
        assert_eq!(
            c.ops_addr().unwrap(),
            Some("127.0.0.1:9464".parse().unwrap())
        );
        for (addr, says) in [("0.0.0.0:9464", "loopback"), ("nine", "127.0.0.1:9464")] {
            let err = Config::load_with_env(None, |v| match v {
                "SKINTIGHT_WORKER_OPS_ADDR" => Some(addr.into()),
                other => open(other),
            })
            .unwrap_err()
            .to_string();
            assert!(
                err.contains("worker.ops_addr") && err.contains(says),
                "{err}"
            );
        }
    }

    #[test]
    fn unauthenticated_server_refuses_public_bind() {
        let err = Config::from_toml_overlay(
            "[server]\nbind = \"0.0.0.0:8080\"\n[auth]\ndisabled = true\n",
        )
        .unwrap_err();
        assert!(err.to_string().contains("loopback"), "{err}");
        assert!(err.to_string().contains("server.bind"), "{err}");
    }

    #[test]
    fn bad_env_and_unknown_keys_are_named() {
        let err =
            Config::load_with_env(None, |v| (v == "SKINTIGHT_WORKERS").then(|| "many".into()))
                .unwrap_err();
        assert!(err.to_string().contains("SKINTIGHT_WORKERS"), "{err}");
        let err = Config::load_with_env(None, |v| match v {
            "SKINTIGHT_AUTH_DISABLED" => Some("true".into()),
            "SKINTIGHT_DATABASE_URL" => Some("mysql://u:secret@db/x".into()),
            _ => None,
        })
        .unwrap_err();
        let text = err.to_string();
        assert!(
            text.contains("database.url") && text.contains("postgres://"),
            "{err}"
        );
        assert!(
            !text.contains("secret"),
            "the password is never shown: {err}"
        );
        let err = Config::from_toml_overlay("[jobs]\nwrokers = 2\n").unwrap_err();
        assert!(err.to_string().contains("wrokers"), "{err}");
    }

    #[test]
    fn the_servers_memory_bounds_its_mesh_budget() {
        let auth = "[auth]\ndisabled = true\n";
        // The default: 512 MiB for the process, half of it for reading meshes.
        let c = Config::from_toml_overlay(auth).unwrap();
        assert_eq!(c.server.max_memory_bytes, 512 << 20);
        assert_eq!(c.server.asset_budget_bytes(), 256 << 20);
        // An explicit budget is kept when it is at most half.
        let c = Config::from_toml_overlay(&format!(
            "{auth}[server]\nmax_memory_bytes = 1000000000\nasset_check_memory_bytes = 400000000\n"
        ))
        .unwrap();
        assert_eq!(c.server.asset_budget_bytes(), 400_000_000);
        // More than half: refused, naming the key and the bound.
        let err = Config::from_toml_overlay(&format!(
            "{auth}[server]\nasset_check_memory_bytes = 300000000\n"
        ))
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("server.asset_check_memory_bytes")
                && err.contains("server.max_memory_bytes"),
            "{err}"
        );
        // A process too small for the largest upload: refused at server.max_memory_bytes.
        let err =
            Config::from_toml_overlay(&format!("{auth}[server]\nmax_memory_bytes = 100000000\n"))
                .unwrap_err()
                .to_string();
        assert!(
            err.contains("server.max_memory_bytes") && err.contains("server.max_asset_bytes"),
            "{err}"
        );
        // The environment names it too.
        let c = Config::load_with_env(None, |v| match v {
            "SKINTIGHT_AUTH_DISABLED" => Some("true".into()),
            "SKINTIGHT_SERVER_MAX_MEMORY_BYTES" => Some("1073741824".into()),
            _ => None,
        })
        .unwrap();
        assert_eq!(c.server.asset_budget_bytes(), 512 << 20);
    }
}
