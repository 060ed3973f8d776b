//! Finds the system liblcm with pkg-config and generates the bindings with bindgen.
//!
//! Debian's `lcm.pc` requires glib's `.pc` files (`libglib2.0-dev`) although the headers do
//! not need glib; when pkg-config fails for that reason we fall back to plain `-llcm` so a
//! machine with only `liblcm-dev` still builds.
//!
//! `LCM_INCLUDE_DIR` and `LCM_LIB_DIR` point the build at another liblcm (a source build, or the
//! SDK inside the `lcm` Python wheel, which ships no `lcm.pc`); pkg-config is then skipped.

use std::env;
use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-changed=wrapper.h");
    println!("cargo:rerun-if-env-changed=LCM_INCLUDE_DIR");
    println!("cargo:rerun-if-env-changed=LCM_LIB_DIR");
    println!("cargo:rustc-check-cfg=cfg(lcm_has_queue_size)");

    let mut include_paths: Vec<PathBuf> = Vec::new();
    let include_dir = env::var_os("LCM_INCLUDE_DIR").map(PathBuf::from);
    let lib_dir = env::var_os("LCM_LIB_DIR").map(PathBuf::from);
    if include_dir.is_some() || lib_dir.is_some() {
        include_paths.extend(include_dir);
        if let Some(dir) = lib_dir {
            println!("cargo:rustc-link-search=native={}", dir.display());
        }
        println!("cargo:rustc-link-lib=lcm");
    } else {
        match pkg_config::Config::new()
            .atleast_version("1.3.1")
            .probe("lcm")
        {
            Ok(lib) => include_paths.extend(lib.include_paths),
            Err(e) => {
                println!(
                    "cargo:warning=pkg-config could not resolve lcm ({e}); linking with -llcm instead"
                );
                println!("cargo:rustc-link-lib=lcm");
            }
        }
    }

    let mut builder = bindgen::Builder::default()
        .header("wrapper.h")
        .allowlist_function("lcm_.*")
        .allowlist_type("lcm_.*")
        .allowlist_var("LCM_.*")
        .opaque_type("_lcm_t")
        .opaque_type("_lcm_subscription_t")
        .blocklist_type("FILE")
        .blocklist_type("_IO_.*")
        .raw_line("/// The C stdio stream type, opaque to Rust.")
        .raw_line("pub type FILE = core::ffi::c_void;")
        .layout_tests(true)
        .generate_comments(true)
        .parse_callbacks(Box::new(bindgen::CargoCallbacks::new()));
    for p in &include_paths {
        builder = builder.clang_arg(format!("-I{}", p.display()));
    }
    let bindings = builder
        .generate()
        .expect("bindgen failed to parse <lcm/lcm.h>; is liblcm-dev installed?");

    // liblcm 1.4 added lcm_subscription_get_queue_size; Debian's 1.3.1 lacks it.
    if bindings
        .to_string()
        .contains("fn lcm_subscription_get_queue_size")
    {
        println!("cargo:rustc-cfg=lcm_has_queue_size");
    }

    let out = PathBuf::from(env::var("OUT_DIR").unwrap()).join("bindings.rs");
    bindings
        .write_to_file(out)
        .expect("could not write bindings.rs");
}
