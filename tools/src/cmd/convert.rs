//! Placeholder until this subcommand lands.

#[derive(Debug, clap::Subcommand)]
pub enum Args {}

pub fn run(args: Args) -> anyhow::Result<()> {
    match args {}
}
