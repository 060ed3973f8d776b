//! Builds the fake Arduino board: the firmware's sketch itself (`firmware/due`), compiled for
//! the host against the Arduino stubs (`firmware/host-stubs`) with the simulated joints and IMU
//! (`c/due_plant.c`) behind them, linked into a shared library that `src/due.rs` loads once per
//! board (each board its own copy of the sketch's statics, as each Due has its own RAM). Also
//! links the link's C codec into this crate, for the test that checks it against the Rust one.

use std::path::{Path, PathBuf};
use std::process::Command;

fn main() {
    let link = Path::new("../arduino-link/c");
    let sketch = Path::new("../../firmware/due/stride_link_due");
    let stubs = Path::new("../../firmware/host-stubs");
    for f in [
        link.join("stride_link.c"),
        link.join("stride_link.h"),
        sketch.join("stride_link_due.ino"),
        stubs.join("Arduino.h"),
        stubs.join("Wire.h"),
        stubs.join("host_board.h"),
        stubs.join("host_board.cpp"),
        "c/due_plant.c".into(),
        "c/due_plant.h".into(),
        "c/due_board.cpp".into(),
    ] {
        println!("cargo:rerun-if-changed={}", f.display());
    }
    // The codec, linked into the crate.
    cc::Build::new()
        .file(link.join("stride_link.c"))
        .include(link)
        .flag_if_supported("-std=c99")
        .warnings(true)
        .compile("stride_link");

    // The board, as a shared library of its own.
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("OUT_DIR"));
    let objects = out.join("due-board");
    std::fs::create_dir_all(&objects).expect("creating the board's object directory");
    let mut c = cc::Build::new();
    c.out_dir(&objects)
        .pic(true)
        .file(link.join("stride_link.c"))
        .file("c/due_plant.c")
        .include(link)
        .include(stubs)
        .include("c")
        .flag_if_supported("-std=c99")
        .flag("-fvisibility=hidden")
        .warnings(true)
        .extra_warnings(true);
    let mut cpp = cc::Build::new();
    cpp.cpp(true)
        .out_dir(&objects)
        .pic(true)
        .file(stubs.join("host_board.cpp"))
        .file("c/due_board.cpp")
        .include(link)
        .include(stubs)
        .include(sketch)
        .include("c")
        .flag("-std=c++11")
        .flag("-fno-exceptions")
        .flag("-fno-rtti")
        .flag("-fvisibility=hidden")
        .flag_if_supported("-fno-gnu-unique")
        .warnings(true)
        .extra_warnings(true);
    let mut objs = c.compile_intermediates();
    objs.extend(cpp.compile_intermediates());
    let lib = out.join("due_board.so");
    let tool = c.get_compiler();
    let status = Command::new(tool.path())
        .args(["-shared", "-o"])
        .arg(&lib)
        .args(&objs)
        .args(["-Wl,--no-undefined", "-Wl,-Bsymbolic", "-lm"])
        .status()
        .expect("running the linker");
    assert!(status.success(), "linking {}", lib.display());
}
