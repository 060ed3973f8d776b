//! Builds the C side of the compatibility tests: lcm-gen's C code for every stride type, plus a
//! harness that decodes bytes with it and encodes them again; and the Rust list of cases. Also
//! the peers of the cross-language value tests (lcm-gen's C, Java and Python code with the
//! dumpers and builders `xlang/gen.py` writes).

use std::fmt::Write;
use std::path::PathBuf;
use std::process::Command;

fn main() {
    let here = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap());
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap());
    let stride_dir = here.join("../lcmtypes/lcm");
    let feature_dir = here.join("lcm");
    let const_dims_dir = here.join("lcm-const-dims");
    for d in [&stride_dir, &feature_dir, &const_dims_dir] {
        println!("cargo:rerun-if-changed={}", d.display());
    }

    // Rust for the feature-test types (the stride types come from stride-lcmtypes).
    let test_opts = lcmgen::rust::Options {
        registry: false,
        serde: lcmgen::rust::Gate::Never,
        random: lcmgen::rust::Gate::Always,
    };
    let feature_files = lcmgen::find_lcm_files(&feature_dir).expect("reading tests/lcm");
    let features = lcmgen::TypeSet::from_files(&feature_files).expect("valid tests/lcm");
    std::fs::write(
        out.join("feature_types.rs"),
        lcmgen::rust::generate(&features, &test_opts),
    )
    .unwrap();
    let const_files =
        lcmgen::find_lcm_files(&const_dims_dir).expect("reading tests/lcm-const-dims");
    let const_dims = lcmgen::TypeSet::from_files(&const_files).expect("valid const-dims types");
    std::fs::write(
        out.join("const_dims_types.rs"),
        lcmgen::rust::generate(&const_dims, &test_opts),
    )
    .unwrap();

    // The C side covers the stride types and the feature-test types.
    let mut files = lcmgen::find_lcm_files(&stride_dir).expect("reading lcmtypes/lcm");
    files.extend(feature_files.iter().cloned());
    let set = lcmgen::TypeSet::from_files(&files).expect("valid .lcm files");
    let cdir = out.join("c");
    let _ = std::fs::remove_dir_all(&cdir);
    std::fs::create_dir_all(&cdir).unwrap();

    // lcm-gen runs one file at a time: it would carry a package over to later files.
    for f in &files {
        let status = Command::new("lcm-gen")
            .args(["-c", "--c-no-pubsub", "--c-cpath"])
            .arg(&cdir)
            .arg("--c-hpath")
            .arg(&cdir)
            .arg(f)
            .status()
            .expect("running lcm-gen (install liblcm-bin: scripts/test does)");
        assert!(status.success(), "lcm-gen failed on {}", f.display());
    }

    let mut harness = String::from("#include <stdint.h>\n");
    let mut decls = String::new();
    let mut cases = String::from("{\n");
    for s in set.structs() {
        let c = s.full_name().replace('.', "_");
        let _ = writeln!(harness, "#include \"{c}.h\"");
        let _ = write!(
            harness,
            "int64_t c_fingerprint_{c}(void) {{ return __{c}_get_hash(); }}\n\
             int c_roundtrip_{c}(const uint8_t *in, int inlen, uint8_t *out, int outcap) {{\n\
             \x20   {c} msg;\n\
             \x20   int r = {c}_decode(in, 0, inlen, &msg);\n\
             \x20   if (r < 0) return -1;\n\
             \x20   if (r != inlen) {{ {c}_decode_cleanup(&msg); return -2; }}\n\
             \x20   int n = {c}_encoded_size(&msg);\n\
             \x20   int w = n <= outcap ? {c}_encode(out, 0, outcap, &msg) : -3;\n\
             \x20   {c}_decode_cleanup(&msg);\n\
             \x20   return w;\n}}\n"
        );
        let in_features = features.get(&s.full_name()).is_some();
        let krate = if in_features {
            "stride_tests::features"
        } else {
            "stride_lcmtypes"
        };
        let mut rust = krate.to_owned();
        for part in s.package.split('.').filter(|p| !p.is_empty()) {
            rust.push_str("::");
            rust.push_str(&lcmgen::rust::ident(part));
        }
        rust.push_str("::");
        rust.push_str(&lcmgen::rust::type_name(&s.name));
        let _ = writeln!(
            decls,
            "extern \"C\" {{ fn c_fingerprint_{c}() -> i64; fn c_roundtrip_{c}(i: *const u8, il: i32, o: *mut u8, oc: i32) -> i32; }}"
        );
        let _ = writeln!(
            cases,
            "    case!({rust}, c_fingerprint_{c}, c_roundtrip_{c});"
        );
    }
    cases.push_str("}\n");
    // Codec benchmark loops, timed in C, for the types the codec benchmark uses.
    harness.push_str("#include <time.h>\n#include <stdlib.h>\n");
    harness.push_str(
        "static int64_t bench_now(void) { struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t); \
         return (int64_t)t.tv_sec * 1000000000LL + t.tv_nsec; }\n",
    );
    for c in [
        "stride_imu_t",
        "stride_joint_trajectory_t",
        "stride_point_cloud_t",
    ] {
        let _ = write!(
            harness,
            "int64_t c_bench_encode_{c}(const uint8_t *in, int len, int iters, uint8_t *out) {{\n\
             \x20   {c} msg;\n\
             \x20   if ({c}_decode(in, 0, len, &msg) != len) return -1;\n\
             \x20   int64_t t0 = bench_now();\n\
             \x20   for (int i = 0; i < iters; i++) {{\n\
             \x20       int n = {c}_encoded_size(&msg);\n\
             \x20       if ({c}_encode(out, 0, n, &msg) != n) return -2;\n\
             \x20   }}\n\
             \x20   int64_t t = bench_now() - t0;\n\
             \x20   {c}_decode_cleanup(&msg);\n\
             \x20   return t;\n}}\n\
             int64_t c_bench_decode_{c}(const uint8_t *in, int len, int iters) {{\n\
             \x20   int64_t t0 = bench_now();\n\
             \x20   for (int i = 0; i < iters; i++) {{\n\
             \x20       {c} msg;\n\
             \x20       if ({c}_decode(in, 0, len, &msg) != len) return -1;\n\
             \x20       {c}_decode_cleanup(&msg);\n\
             \x20   }}\n\
             \x20   return bench_now() - t0;\n}}\n"
        );
    }
    std::fs::write(cdir.join("harness.c"), harness).unwrap();
    std::fs::write(out.join("compat_decls.rs"), decls).unwrap();
    std::fs::write(out.join("compat_cases.rs"), cases).unwrap();

    let mut build = cc::Build::new();
    build.include(&cdir).warnings(false).opt_level(2);
    for entry in std::fs::read_dir(&cdir).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().is_some_and(|e| e == "c") {
            build.file(p);
        }
    }
    build.compile("stride_c_types");

    build_legacy_controller(&here, &out, &files);
    build_xlang_peers(&here, &out, &cdir, &files);
}

/// The peers of the cross-language value tests (`tests/tests/xlang.rs`): `tests/xlang/gen.py`
/// writes value dumpers and builders for C, Java, Python and Rust from the .lcm files; here
/// lcm-gen writes its Java and Python code beside them, and the C peer is linked with
/// lcm-gen's C code. The Java is compiled by the test (`javac` is slow to start).
fn build_xlang_peers(
    here: &std::path::Path,
    out: &std::path::Path,
    cdir: &std::path::Path,
    files: &[PathBuf],
) {
    let gen = here.join("xlang/gen.py");
    println!("cargo:rerun-if-changed={}", gen.display());
    let dir = out.join("xlang");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let status = Command::new("python3")
        .arg(&gen)
        .arg(&dir)
        .arg(format!(
            "stride_lcmtypes={}",
            here.join("../lcmtypes/lcm").display()
        ))
        .arg(format!(
            "stride_tests::features={}",
            here.join("lcm").display()
        ))
        .status()
        .expect("running python3 (install python3: scripts/test does)");
    assert!(status.success(), "tests/xlang/gen.py failed");
    for f in files {
        for (lang, flag) in [("java", "--jpath"), ("py", "--ppath")] {
            let status = Command::new("lcm-gen")
                .arg(format!("-{}", &lang[..1]))
                .arg(flag)
                .arg(dir.join(lang))
                .arg(f)
                .stdout(std::process::Stdio::null())
                .status()
                .expect("running lcm-gen");
            assert!(
                status.success(),
                "lcm-gen -{lang} failed on {}",
                f.display()
            );
        }
    }
    let exe = dir.join("xlang-c-peer");
    let mut cmd = cc::Build::new().get_compiler().to_command();
    cmd.args(["-O1", "-std=gnu99", "-I"]).arg(cdir);
    for entry in std::fs::read_dir(cdir).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().is_some_and(|e| e == "c") && !p.ends_with("harness.c") {
            cmd.arg(p);
        }
    }
    cmd.arg(dir.join("c/xlang_peer.c")).arg("-o").arg(&exe);
    let status = cmd.status().expect("running the C compiler");
    assert!(
        status.success(),
        "building the C peer of tests/xlang failed"
    );
    println!("cargo:rustc-env=STRIDE_XLANG={}", dir.display());
}

/// The legacy C controller (`tests/c/legacy_controller.c`), linked with lcm-gen's C code
/// (publish/subscribe included) and liblcm, as a lab would build it.
fn build_legacy_controller(here: &std::path::Path, out: &std::path::Path, files: &[PathBuf]) {
    let src = here.join("c/legacy_controller.c");
    println!("cargo:rerun-if-changed={}", src.display());
    let gen = out.join("c-pubsub");
    let _ = std::fs::remove_dir_all(&gen);
    std::fs::create_dir_all(&gen).unwrap();
    for f in files
        .iter()
        .filter(|f| f.starts_with(here.join("../lcmtypes")))
    {
        let status = Command::new("lcm-gen")
            .args(["-c", "--c-cpath"])
            .arg(&gen)
            .arg("--c-hpath")
            .arg(&gen)
            .arg(f)
            .status()
            .expect("running lcm-gen");
        assert!(status.success(), "lcm-gen failed on {}", f.display());
    }
    let exe = out.join("legacy-controller");
    let compiler = cc::Build::new().get_compiler();
    let mut cmd = compiler.to_command();
    cmd.arg("-O2")
        .arg("-std=gnu99")
        .arg("-I")
        .arg(&gen)
        .arg(&src);
    for entry in std::fs::read_dir(&gen).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().is_some_and(|e| e == "c") {
            cmd.arg(p);
        }
    }
    cmd.arg("-o").arg(&exe).args(["-llcm", "-lm"]);
    let status = cmd.status().expect("running the C compiler");
    assert!(status.success(), "building legacy_controller failed");
    println!("cargo:rustc-env=STRIDE_LEGACY_CONTROLLER={}", exe.display());
}
