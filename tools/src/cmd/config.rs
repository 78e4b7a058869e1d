//! `echofield config`: the default configuration with each key's
//! documentation, as a TOML file `run --config` accepts.

use clap::Parser;

#[derive(Debug, Parser)]
#[command(after_help = "Examples:
  # every key, documented: edit the file and pass it to run --config
  echofield config > my.toml
  # one section with its sub-tables, or one sub-table
  echofield config --section loops
  echofield config --section loops.gate
  # how many keys have a default
  echofield config --list-keys | wc -l")]
pub struct Args {
    /// Print only this section (`loops`) or sub-table (`loops.gate`).
    #[arg(long, value_name = "NAME")]
    pub section: Option<String>,
    /// Print the full path of each key (`loops.gate.max_window`), one a
    /// line, instead of the documented TOML. The optional keys without a
    /// default (listed in the header of `echofield config`) are not among
    /// them.
    #[arg(long)]
    pub list_keys: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    use echofield::config_doc::{DOCUMENTED_DEFAULTS, key_paths, section};
    let text = match &args.section {
        None => DOCUMENTED_DEFAULTS.to_string(),
        Some(name) => section(DOCUMENTED_DEFAULTS, name)?,
    };
    if args.list_keys {
        for key in key_paths(&text)? {
            println!("{key}");
        }
    } else {
        print!("{text}");
    }
    Ok(())
}
