//! Generates the Rust code of every `.lcm` file under `lcm/` into OUT_DIR.

use std::path::PathBuf;

fn main() {
    let dir = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap()).join("lcm");
    println!("cargo:rerun-if-changed={}", dir.display());
    let files = lcmgen::find_lcm_files(&dir).expect("reading lcmtypes/lcm");
    for f in &files {
        println!("cargo:rerun-if-changed={}", f.display());
    }
    let set = match lcmgen::TypeSet::from_files(&files) {
        Ok(set) => set,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
    };
    let code = lcmgen::rust::generate(&set, &lcmgen::rust::Options::default());
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap()).join("lcmtypes.rs");
    std::fs::write(out, code).expect("writing the generated code");
}
