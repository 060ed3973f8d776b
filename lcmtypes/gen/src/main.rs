//! `stride-lcm-gen`: Rust from `.lcm` files, byte-compatible with lcm-gen.

use std::path::PathBuf;

use clap::Parser;

/// Generate Rust code (one module per LCM package) from LCM type definitions.
///
/// The output depends on the `lcm` crate. Include it at any module level with
/// `include!("path/to/output.rs")`. Every referenced type must be among the inputs.
#[derive(Parser, Debug)]
#[command(version, about, long_about)]
struct Cli {
    /// .lcm files, or directories searched for them.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Output file ("-" for standard output).
    #[arg(short, long, default_value = "-")]
    output: PathBuf,
    /// Do not emit the TYPES table, decode_json and json_schema.
    #[arg(long)]
    no_registry: bool,
    /// Print each type's fingerprint instead of code.
    #[arg(long)]
    fingerprints: bool,
}

fn main() {
    let cli = Cli::parse();
    if let Err(e) = run(cli) {
        eprintln!("stride-lcm-gen: {e}");
        std::process::exit(1);
    }
}

fn run(cli: Cli) -> Result<(), Box<dyn std::error::Error>> {
    let mut files = Vec::new();
    for input in &cli.inputs {
        if input.is_dir() {
            files.extend(lcmgen::find_lcm_files(input)?);
        } else {
            files.push(input.clone());
        }
    }
    let set = lcmgen::TypeSet::from_files(&files)?;
    let text = if cli.fingerprints {
        set.structs()
            .map(|s| {
                let n = s.full_name();
                format!("{:#018x} {n}\n", set.fingerprint(&n))
            })
            .collect()
    } else {
        lcmgen::rust::generate(
            &set,
            &lcmgen::rust::Options {
                registry: !cli.no_registry,
                ..Default::default()
            },
        )
    };
    if cli.output.as_os_str() == "-" {
        print!("{text}");
    } else {
        std::fs::write(&cli.output, text)?;
    }
    Ok(())
}
