//! `polycal`: the command line over the polycal library. This file parses the arguments,
//! dispatches to the command (`cli/`), and prints the final `error:` line; all logic
//! lives in the library's modules.

mod cli;

use std::process::ExitCode;

use cli::output::Output;

fn main() -> ExitCode {
    let cli = cli::Cli::parse_args();
    let out = Output::new(cli.global.color, cli.global.quiet);
    match cli::dispatch(cli.command, &out) {
        Ok(code) => ExitCode::from(code),
        Err(error) => {
            cli::wait_if_interrupted();
            if cli::stdout::is_closed(&error) {
                // Standard output closed by its reader (`| head`): not an error, no
                // line (docs/FORMAT.md §8).
                return ExitCode::from(cli::stdout::EXIT_CLOSED);
            }
            out.error(&error);
            ExitCode::from(cli::EXIT_ERROR)
        }
    }
}
