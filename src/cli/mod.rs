//! The command-line interface. Each subcommand lives in its own module; every failure reaches the user as
//! one line on standard error naming the problem, with a non-zero exit status:
//! 2 for unusable input (a bad file, a bad argument), 1 for a failure while working.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

pub mod body;
pub mod design;
pub mod knit;
pub mod mesh;
pub mod simulate;

/// Designs the sewing patterns of skintight garments for one customer's body.
#[derive(Debug, Parser)]
#[command(name = "skintight", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Inspect and convert mesh files (OBJ, PLY, STL, glTF binary).
    Mesh {
        #[command(subcommand)]
        command: mesh::MeshCommand,
    },
    /// Build deformable tetrahedral bodies.
    #[command(subcommand)]
    Body(body::BodyCommand),
    /// Simulate a garment worn on a body at equilibrium (scene JSON in, result.json, .glb and .svg out).
    ///
    /// Exit status: 0 converged, 3 not converged (results still written), 2 bad scene, 1 failure.
    Simulate(simulate::SimulateArgs),
    /// Design the patterns: optimize their shapes until the worn garment meets the job's objectives
    /// (design job JSON in; the simulate outputs of the best design and history.json out).
    ///
    /// Exit status: 0 done (the best design is written), 2 bad job, 1 failure.
    Design(design::DesignArgs),
    /// Yarn-level knitwear: the periodic cell check against published yarn-level results, tiling.
    ///
    /// Exit status of `knit cell`: 0 converged, 3 not converged (report still printed), 2 bad input, 1 failure.
    #[command(subcommand)]
    Knit(knit::KnitCommand),
    /// Runs one job of the service in a process of its own (started by `serve`; not for direct use).
    #[command(hide = true)]
    JobRun,
    /// Runs the HTTP/JSON service until SIGINT or SIGTERM (see docs/API.md).
    Serve {
        /// A TOML file overriding keys of the built-in config/default.toml; environment variables
        /// SKINTIGHT_… override both.
        #[arg(long, value_name = "FILE")]
        config: Option<std::path::PathBuf>,
        /// An API-only node: accept, list and stream jobs, run none (worker nodes, `skintight worker`,
        /// run them; needs a PostgreSQL database.url shared with them).
        #[arg(long)]
        no_workers: bool,
    },
    /// Runs only workers (`jobs.workers` of them), no API port (an optional ops port), until SIGINT or SIGTERM: a worker node
    /// claiming jobs from the PostgreSQL database (database.url) that API nodes fill. A graceful stop hands
    /// its running jobs back at once.
    Worker {
        /// A TOML file overriding keys of the built-in config/default.toml (the same file as `serve`'s);
        /// environment variables SKINTIGHT_… override both.
        #[arg(long, value_name = "FILE")]
        config: Option<std::path::PathBuf>,
        /// Serve GET /healthz, /readyz (the store and this node's leases) and /metrics (this node's
        /// counters, operator key) on this address, e.g. 127.0.0.1:9464 (overrides worker.ops_addr,
        /// SKINTIGHT_WORKER_OPS_ADDR); without it and them, no port.
        #[arg(long, value_name = "HOST:PORT")]
        ops_addr: Option<String>,
    },
}

/// A failure of a subcommand, reported as one line.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// The input cannot be used (exit status 2).
    #[error("{0}")]
    Input(String),
    /// The work failed (exit status 1).
    #[error("{0}")]
    Failed(String),
}

impl CliError {
    fn exit_code(&self) -> u8 {
        match self {
            CliError::Input(_) => 2,
            CliError::Failed(_) => 1,
        }
    }
}

/// Parses the arguments, runs the subcommand and turns any error into one line and an exit status.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(code) => code,
        Err(e) => {
            let line = e.to_string().replace('\n', " ");
            eprintln!("error: {line}");
            ExitCode::from(e.exit_code())
        }
    }
}

/// Runs one parsed command; the exit status of a command that succeeded: 0, 3 for a simulation that did
/// not converge, 4 for a simulation or design that converged to a garment that is not admissible (beyond
/// its fabric's limits; the results are written and say why).
pub fn run(cli: Cli) -> Result<ExitCode, CliError> {
    let done = match cli.command {
        Command::Mesh { command } => mesh::run(command),
        Command::Body(cmd) => body::run(cmd),
        Command::Simulate(args) => {
            return simulate::simulate(args).map(|outcome| match outcome {
                simulate::SimulateExit::Converged => ExitCode::SUCCESS,
                simulate::SimulateExit::NotConverged => ExitCode::from(3),
                simulate::SimulateExit::NotAdmissible => ExitCode::from(4),
            });
        }
        Command::Design(args) => {
            return design::design(args).map(|admissible| {
                if admissible {
                    ExitCode::SUCCESS
                } else {
                    ExitCode::from(4)
                }
            });
        }
        Command::Knit(cmd) => {
            return knit::run(cmd).map(|converged| {
                if converged {
                    ExitCode::SUCCESS
                } else {
                    ExitCode::from(3)
                }
            });
        }
        Command::Serve { config, no_workers } => {
            serve(config.as_deref(), Role::Serve { no_workers })
        }
        Command::Worker { config, ops_addr } => serve(config.as_deref(), Role::Worker { ops_addr }),
        Command::JobRun => return Ok(crate::server::job_process::child_main()),
    };
    done.map(|()| ExitCode::SUCCESS)
}

/// What a service process runs.
enum Role {
    /// `skintight serve [--no-workers]`.
    Serve { no_workers: bool },
    /// `skintight worker [--ops-addr HOST:PORT]`.
    Worker { ops_addr: Option<String> },
}

/// `skintight serve` and `skintight worker`.
fn serve(config: Option<&std::path::Path>, role: Role) -> Result<(), CliError> {
    let mut config =
        crate::server::Config::load(config).map_err(|e| CliError::Input(e.to_string()))?;
    if let Role::Worker {
        ops_addr: Some(addr),
    } = &role
    {
        config.worker.ops_addr = addr.clone();
        config
            .check()
            .map_err(|e| CliError::Input(format!("--ops-addr: {e}")))?;
    }
    let separate = matches!(role, Role::Worker { .. } | Role::Serve { no_workers: true });
    if separate && !config.database.is_postgres() {
        let how = match role {
            Role::Worker { .. } => "skintight worker",
            Role::Serve { .. } => "skintight serve --no-workers",
        };
        return Err(CliError::Input(format!(
            "{how} shares its jobs with other nodes through a PostgreSQL database: set database.url \
             (SKINTIGHT_DATABASE_URL) to postgres://user:password@host:port/database; with SQLite \
             (database.path) one `skintight serve` runs both the API and the workers"
        )));
    }
    crate::server::init_logging(&config);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .map_err(|e| CliError::Failed(format!("cannot start the async runtime: {e}")))?;
    let run = async move {
        match role {
            Role::Serve { no_workers } => crate::server::serve(config, !no_workers).await,
            Role::Worker { .. } => crate::server::work(config).await,
        }
    };
    runtime.block_on(run).map_err(|e| match e {
        crate::server::ServerError::Config(c) => CliError::Input(c.to_string()),
        other => CliError::Failed(other.to_string()),
    })
}
