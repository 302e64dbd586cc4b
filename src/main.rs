//! The `skintight` command-line tool. See `skintight --help`.

fn main() -> std::process::ExitCode {
    skintight::cli::main()
}
