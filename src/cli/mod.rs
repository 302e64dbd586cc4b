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

/// `--help` of a command that ends 0 when done: `body …`, `knit tile`.
pub const EXIT_DONE: &str = "Exit status: 0 done, 2 unusable input (a bad file or argument; the line names \
                             it), 1 failure while working.";
/// `--help` of `mesh` and its subcommands.
pub const EXIT_MESH: &str = "Exit status: 0 done (`mesh inspect`: the mesh can serve as a body), 1 `mesh \
                             inspect`: the mesh cannot serve as a body (after the report), or a failure \
                             while working, 2 the file cannot be read or written (or a bad argument).";
/// `--help` of `simulate`.
pub const EXIT_SIMULATE: &str = "Exit status: 0 converged to an admissible garment, 4 converged but not \
                                 admissible (beyond the fabric's limits or its prescription; results \
                                 written, the last line says what failed), 3 not converged (results still \
                                 written), 2 bad scene (the line names the key), 1 failure.";
/// `--help` of `design`.
pub const EXIT_DESIGN: &str = "Exit status: 0 done (the best design is written) and the garment is \
                               admissible and meets its prescription, 4 done but the final garment is not \
                               admissible (beyond the fabric's limits, its prescription missed, or its final \
                               equilibrium not converged; results written, the last line says what failed), \
                               2 bad job (the line names the key), 1 failure (e.g. a body the garment cannot \
                               be cut on).";
/// `--help` of `knit` and its subcommands.
pub const EXIT_KNIT: &str = "Exit status: 0 done (`knit cell`: converged), 3 `knit cell`: not converged \
                             (report still printed), `knit simulate-yarn`: time steps whose Newton solve \
                             stopped early, 2 bad input, 1 failure.";
/// `--help` of `serve` and `worker`.
pub const EXIT_SERVE: &str = "Exit status: 0 stopped by SIGINT or SIGTERM, 2 bad configuration (the line \
                              names the key), 1 failure.";
/// `--help` of `skintight` itself.
const EXIT_ALL: &str = "Exit status: 0 done, 4 a simulated or designed garment that is not admissible \
                        (results written), 3 not converged (results written), 2 unusable input (the line \
                        names it), 1 failure; `skintight COMMAND --help` gives each command's.";

/// Designs the sewing patterns of skintight garments for one customer's body.
#[derive(Debug, Parser)]
#[command(name = "skintight", version, about, after_help = EXIT_ALL)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Inspect and convert mesh files (OBJ, PLY, STL, glTF binary).
    #[command(after_help = EXIT_MESH)]
    Mesh {
        #[command(subcommand)]
        command: mesh::MeshCommand,
    },
    /// Build deformable tetrahedral bodies.
    #[command(subcommand, after_help = EXIT_DONE)]
    Body(body::BodyCommand),
    /// Simulate a garment worn on a body at equilibrium (scene JSON in, result.json, .glb and .svg out).
    #[command(after_help = EXIT_SIMULATE)]
    Simulate(simulate::SimulateArgs),
    /// Design the patterns: optimize their shapes until the worn garment meets the job's objectives
    /// (design job JSON in; the simulate outputs of the best design and history.json out).
    #[command(after_help = EXIT_DESIGN)]
    Design(design::DesignArgs),
    /// Yarn-level knitwear: the periodic cell check against published yarn-level results, tiling.
    #[command(subcommand, after_help = EXIT_KNIT)]
    Knit(knit::KnitCommand),
    /// Runs one job of the service in a process of its own (started by `serve`; not for direct use).
    #[command(hide = true)]
    JobRun,
    /// Runs the HTTP/JSON service until SIGINT or SIGTERM (see docs/API.md).
    #[command(after_help = EXIT_SERVE)]
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
    #[command(after_help = EXIT_SERVE)]
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

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    use super::Cli;

    /// Every command's `--help` (and `-h`) ends with its exit statuses; `design`'s and `simulate`'s name 4,
    /// the status of a garment that is not admissible.
    #[test]
    fn every_command_lists_its_exit_statuses() {
        fn walk(cmd: &mut clap::Command, path: String, seen: &mut Vec<String>) {
            if cmd.is_hide_set() {
                return;
            }
            let help = cmd.render_long_help().to_string();
            assert!(help.contains("Exit status: 0"), "{path} --help:\n{help}");
            if path.ends_with(" design") || path.ends_with(" simulate") {
                assert!(help.contains(", 4 "), "{path} --help:\n{help}");
            }
            seen.push(path.clone());
            let names: Vec<String> = cmd
                .get_subcommands()
                .map(|c| c.get_name().to_string())
                .filter(|n| n != "help")
                .collect();
            for name in names {
                let sub = cmd.find_subcommand_mut(&name).expect("listed");
                walk(sub, format!("{path} {name}"), seen);
            }
        }
        let mut cmd = Cli::command();
        cmd.build();
        let mut seen = Vec::new();
        walk(&mut cmd, "skintight".into(), &mut seen);
        for needed in [
            "skintight mesh inspect",
            "skintight body prepare",
            "skintight knit tile",
        ] {
            assert!(
                seen.iter().any(|s| s == needed),
                "{needed} not walked: {seen:?}"
            );
        }
    }
}
