//! `cdlab config`: print the commented default configuration, check a file, or print the
//! configuration a run was made with.

use std::path::PathBuf;

use crate::config::Config;

/// Arguments of `cdlab config`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print the default configuration file, with a comment on every key.
    #[arg(long)]
    pub print_default: bool,
    /// Validate a configuration file (parse, units, ranges) and report the first problem.
    #[arg(long, value_name = "FILE")]
    pub check: Option<PathBuf>,
    /// Print the configuration a run was made with (TOML, SI units), from its record (or
    /// an archived test's `config.toml`).
    #[arg(long, value_name = "RUN_DIR")]
    pub of: Option<PathBuf>,
}

/// Runs `cdlab config`.
pub fn run(args: &Args) -> crate::Result<()> {
    if args.print_default {
        print!("{}", Config::default_toml());
    }
    if let Some(path) = &args.check {
        // Range errors name the key but not the file; add it, the user may check several.
        Config::load(path).map_err(|e| match e {
            crate::Error::Invalid { .. } => crate::Error::Other(format!("{}: {e}", path.display())),
            e => e,
        })?;
        println!("{}: ok", path.display());
    }
    if let Some(dir) = &args.of {
        let config = crate::record::read_config(dir)?;
        print!(
            "# The configuration of the run in {} (SI units)\n{}",
            dir.display(),
            config.to_toml_string()?
        );
    }
    if !args.print_default && args.check.is_none() && args.of.is_none() {
        return Err(crate::Error::Other(
            "cdlab config: give --print-default, --check FILE or --of RUN_DIR".into(),
        ));
    }
    Ok(())
}
