//! Builds the fake Arduino board: the firmware's C link codec and the board simulation.

fn main() {
    let link = std::path::Path::new("../arduino-link/c");
    for f in [
        link.join("stride_link.c"),
        link.join("stride_link.h"),
        "c/fake_due.c".into(),
        "c/fake_due.h".into(),
    ] {
        println!("cargo:rerun-if-changed={}", f.display());
    }
    cc::Build::new()
        .file(link.join("stride_link.c"))
        .file("c/fake_due.c")
        .include(link)
        .include("c")
        .flag_if_supported("-std=c99")
        .warnings(true)
        .compile("fake_due");
    println!("cargo:rustc-link-lib=m");
}
