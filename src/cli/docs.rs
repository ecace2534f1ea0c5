//! `polycal completions` and `polycal man`: the command line described for shells and
//! for `man`, generated from the same definitions as the parser.

use std::io::Write;

use anyhow::{Context, Result, bail};
use clap::CommandFactory;
use clap_complete::Shell;

use super::{Cli, EXIT_OK};

/// After `polycal completions --help`.
pub const COMPLETIONS_EXAMPLES: &str = "\
Examples:
  polycal completions bash > ~/.local/share/bash-completion/completions/polycal
  polycal completions zsh > ~/.zfunc/_polycal
  polycal completions fish > ~/.config/fish/completions/polycal.fish
  polycal completions powershell >> $PROFILE";

/// After `polycal man --help`.
pub const MAN_EXAMPLES: &str = "\
Examples:
  polycal man | man -l -
  polycal man > ~/.local/share/man/man1/polycal.1
  polycal man solve | man -l -";

/// Arguments of `polycal completions`.
#[derive(clap::Args)]
pub struct CompletionsArgs {
    /// The shell.
    #[arg(value_enum)]
    shell: Shell,
}

/// Arguments of `polycal man`.
#[derive(clap::Args)]
pub struct ManArgs {
    /// The page of one command (polycal-COMMAND(1)) instead of polycal(1).
    command: Option<String>,
}

/// `polycal completions SHELL`: the completion script on standard output.
pub fn completions(args: &CompletionsArgs) -> Result<u8> {
    let mut command = Cli::command();
    let mut script = Vec::new();
    clap_complete::generate(args.shell, &mut command, "polycal", &mut script);
    write_stdout(&script)?;
    Ok(EXIT_OK)
}

/// `polycal man [COMMAND]`: the roff manual page on standard output.
pub fn man(args: &ManArgs) -> Result<u8> {
    let mut command = Cli::command();
    command.build();
    let page = match &args.command {
        None => command,
        Some(name) => {
            let Some(sub) = command.find_subcommand(name) else {
                bail!(
                    "no command {name:?}; the commands are {}",
                    super::command_names().join(", ")
                );
            };
            // Built, a command's display name is `polycal-solve` (the page's title) and
            // its binary name `polycal solve` (its usage).
            sub.clone().version(env!("CARGO_PKG_VERSION"))
        }
    };
    let mut roff = Vec::new();
    clap_mangen::Man::new(page)
        .render(&mut roff)
        .context("cannot render the manual page")?;
    write_stdout(&roff)?;
    Ok(EXIT_OK)
}

fn write_stdout(bytes: &[u8]) -> Result<()> {
    let stdout = super::stdout::stdout();
    let mut stdout = stdout.lock();
    stdout.write_all(bytes)?;
    stdout.flush()?;
    Ok(())
}
