//! Values, not just bytes: every stride type (and every feature-test type of `tests/lcm`)
//! against the code lcm-gen writes for C, Java and Python, field by field, both ways.
//!
//! Rust draws random instances with edge values ([`Rng::with_edges`]: NaN, infinities,
//! signed zeros, subnormals, integers' extremes, empty and long arrays, long and non-ASCII
//! UTF-8 strings) and encodes them. Each peer decodes the bytes with lcm-gen's code and
//! prints every leaf field as `PATH VALUE` (floats as their bits, strings as the hex of
//! their UTF-8 bytes),
//! which must be what Rust's own dump of the instance says. The other way, each peer reads
//! that text, builds lcm-gen's object from it and encodes it; Rust decodes those bytes, and
//! its dump of what it decoded must again be the text.
//!
//! The dumpers and builders of all four languages are written by `tests/xlang/gen.py` from
//! the .lcm files with a parser of its own; the Rust dumper only reads struct fields, so it
//! shares no code with the codec it checks, and the peers call nothing of stride's. NaN is
//! compared as NaN, not by its sign and payload bits: lcm-gen's Java writes every NaN as
//! Java's one NaN, and Python widens a float to a double, which may change a NaN's bits.
//!
//! lcm-gen 1.3.1's Java keeps a string's bytes one to a `char` (Latin-1) both ways, so its
//! dumper and builder read and write strings that way: a Java program handing it a
//! `String` with a character above U+00FF sends a truncated byte, not UTF-8. Its Java for
//! `lcmtest.multidim_t` does not compile, so the Java peer leaves that type out
//! (`gen.py`'s `SKIPS`).

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;

use lcm::{Message, Random, Rng};

/// Random instances per type (the first one is the type's default: all zeros, all empty).
const INSTANCES: usize = 64;
/// Array elements one instance may draw.
const BUDGET: u64 = 600;

/// The canonical text of a message: one `PATH VALUE` line per leaf field.
#[derive(Default)]
pub struct Dump {
    path: String,
    out: String,
}

impl Dump {
    /// Enters the member `name`; returns what [`Dump::restore`] needs to leave it.
    pub fn field(&mut self, name: &str) -> usize {
        let s = self.path.len();
        if s > 0 {
            self.path.push('.');
        }
        self.path.push_str(name);
        s
    }

    /// Enters element `i` of an array.
    pub fn index(&mut self, i: usize) -> usize {
        let s = self.path.len();
        let _ = write!(self.path, "[{i}]");
        s
    }

    /// Leaves what [`Dump::field`] or [`Dump::index`] entered.
    pub fn restore(&mut self, s: usize) {
        self.path.truncate(s);
    }

    fn line(&mut self, v: std::fmt::Arguments) {
        let _ = writeln!(self.out, "{} {v}", self.path);
    }

    /// An integer of any width (and a byte, unsigned).
    pub fn int(&mut self, v: i64) {
        self.line(format_args!("{v}"));
    }

    /// A boolean.
    pub fn bool(&mut self, v: bool) {
        self.line(format_args!("{v}"));
    }

    /// A float: its bits, or `nan`.
    pub fn f32(&mut self, v: f32) {
        if v.is_nan() {
            self.line(format_args!("nan"));
        } else {
            self.line(format_args!("f:{:08x}", v.to_bits()));
        }
    }

    /// A double: its bits, or `nan`.
    pub fn f64(&mut self, v: f64) {
        if v.is_nan() {
            self.line(format_args!("nan"));
        } else {
            self.line(format_args!("d:{:016x}", v.to_bits()));
        }
    }

    /// A string: the hex of its UTF-8 bytes.
    pub fn string(&mut self, v: &str) {
        self.line(format_args!("s:{}", hex(v.as_bytes())));
    }
}

/// The dumpers `tests/xlang/gen.py` wrote.
mod gen {
    use super::Dump;
    include!(concat!(env!("STRIDE_XLANG"), "/rust/dump.rs"));
}

fn hex(b: &[u8]) -> String {
    let mut s = String::with_capacity(2 * b.len());
    for x in b {
        let _ = write!(s, "{x:02x}");
    }
    s
}

fn unhex(h: &str) -> Result<Vec<u8>, String> {
    if !h.len().is_multiple_of(2) {
        return Err(format!("odd hex length {}", h.len()));
    }
    (0..h.len() / 2)
        .map(|i| u8::from_str_radix(&h[2 * i..2 * i + 2], 16).map_err(|e| e.to_string()))
        .collect()
}

/// One random instance: its type, number, Rust's bytes and Rust's dump of it.
struct Sample {
    ty: &'static str,
    index: usize,
    bytes: Vec<u8>,
    text: String,
}

/// Rust's side of one type: its LCM name and "decode these bytes and dump what you got".
struct Kind {
    ty: &'static str,
    redump: fn(&[u8]) -> Result<String, String>,
}

fn draw<M: Message + Random + Default>(
    ty: &'static str,
    dump: fn(&M, &mut Dump),
    out: &mut Vec<Sample>,
) {
    let mut rng = Rng::with_edges(M::FINGERPRINT ^ 0x5eed);
    for index in 0..INSTANCES {
        rng.set_budget(BUDGET);
        let msg = if index == 0 {
            M::default()
        } else {
            M::random(&mut rng)
        };
        let mut d = Dump::default();
        dump(&msg, &mut d);
        let bytes = msg
            .encode()
            .unwrap_or_else(|e| panic!("{ty} #{index}: {e}"));
        out.push(Sample {
            ty,
            index,
            bytes,
            text: d.out,
        });
    }
}

fn redump<M: Message>(bytes: &[u8], dump: fn(&M, &mut Dump)) -> Result<String, String> {
    let msg = M::decode(bytes).map_err(|e| e.to_string())?;
    let mut d = Dump::default();
    dump(&msg, &mut d);
    Ok(d.out)
}

/// Every type's random instances, and Rust's decoder of each type.
fn corpus() -> &'static (Vec<Sample>, HashMap<&'static str, Kind>) {
    static CORPUS: OnceLock<(Vec<Sample>, HashMap<&'static str, Kind>)> = OnceLock::new();
    CORPUS.get_or_init(|| {
        let mut samples = Vec::new();
        let mut kinds = HashMap::new();
        macro_rules! case {
            ($name:literal, $t:ty, $dump:path) => {{
                draw::<$t>($name, $dump, &mut samples);
                kinds.insert(
                    $name,
                    Kind {
                        ty: $name,
                        redump: |b: &[u8]| redump::<$t>(b, $dump),
                    },
                );
            }};
        }
        {
            use gen::*;
            include!(concat!(env!("STRIDE_XLANG"), "/rust/cases.rs"));
        }
        // Every stride type, and the 7 feature-test types of tests/lcm.
        assert_eq!(kinds.len(), stride_lcmtypes::TYPES.len() + 7);
        (samples, kinds)
    })
}

fn xlang_dir() -> PathBuf {
    PathBuf::from(env!("STRIDE_XLANG"))
}

/// A peer: its name and how to start it with `decode` or `encode`.
struct Peer {
    name: &'static str,
    command: fn(&str) -> Command,
}

impl Peer {
    fn skips(&self, ty: &str) -> bool {
        gen::SKIPS
            .iter()
            .any(|(p, t, _)| *p == self.name && *t == ty)
    }

    /// Runs the peer on `input`; its standard output.
    fn run(&self, mode: &str, input: &str) -> String {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("input");
        std::fs::write(&path, input).unwrap();
        let out = (self.command)(mode)
            .stdin(std::fs::File::open(&path).unwrap())
            .stderr(Stdio::piped())
            .output()
            .unwrap_or_else(|e| panic!("starting the {} peer: {e}", self.name));
        assert!(
            out.status.success(),
            "the {} peer ({mode}) failed: {}\n{}",
            self.name,
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).expect("a peer prints ASCII")
    }
}

const C: Peer = Peer {
    name: "c",
    command: |mode| {
        let mut c = Command::new(xlang_dir().join("xlang-c-peer"));
        c.arg(mode);
        c
    },
};

const PYTHON: Peer = Peer {
    name: "python",
    command: |mode| {
        let mut c = Command::new("python3");
        c.arg(xlang_dir().join("py/xlang_peer.py"))
            .arg(mode)
            .env("PYTHONDONTWRITEBYTECODE", "1");
        c
    },
};

const JAVA: Peer = Peer {
    name: "java",
    command: |mode| {
        let mut c = Command::new("java");
        c.arg("-cp")
            .arg(format!(
                "/usr/share/java/lcm.jar:{}",
                java_classes().display()
            ))
            .args(["XlangPeer", mode]);
        c
    },
};

/// lcm-gen's Java classes and the Java peer, compiled once per test run (into the build
/// script's output, beside their sources).
fn java_classes() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = xlang_dir().join("java-classes");
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let src = xlang_dir().join("java");
        let skipped: Vec<PathBuf> = gen::SKIPS
            .iter()
            .filter(|(p, _, _)| *p == "java")
            .map(|(_, t, _)| {
                let t = if t.contains('.') {
                    t.to_string()
                } else {
                    format!("lcmtypes.{t}")
                };
                src.join(format!("{}.java", t.replace('.', "/")))
            })
            .collect();
        let mut files = Vec::new();
        let mut todo = vec![src];
        while let Some(d) = todo.pop() {
            for e in std::fs::read_dir(d).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    todo.push(p);
                } else if p.extension().is_some_and(|x| x == "java") && !skipped.contains(&p) {
                    files.push(p);
                }
            }
        }
        let out = Command::new("javac")
            .args([
                "-nowarn",
                "-encoding",
                "UTF-8",
                "-cp",
                "/usr/share/java/lcm.jar",
                "-d",
            ])
            .arg(&dir)
            .args(&files)
            .output()
            .expect("javac (install default-jdk-headless: scripts/test does)");
        assert!(
            out.status.success(),
            "javac failed:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        dir
    })
}

/// A value for a message: long strings shortened to their length and first bytes.
fn shown(v: &str) -> String {
    match v.strip_prefix("s:") {
        Some(h) if h.len() > 48 => format!("s:{}... ({} bytes)", &h[..48], h.len() / 2),
        _ => v.to_owned(),
    }
}

/// Where `got` first differs from `want` (both dumps of `s`), in words; `want_is` and
/// `got_is` say whose values they are.
fn difference(s: &Sample, want: &str, got: &str, want_is: &str, got_is: &str) -> Option<String> {
    if want == got {
        return None;
    }
    let (mut w, mut g) = (want.lines(), got.lines());
    let at = format!("{} #{}", s.ty, s.index);
    loop {
        match (w.next(), g.next()) {
            (Some(a), Some(b)) if a == b => continue,
            (Some(a), Some(b)) => {
                let (pa, va) = a.split_once(' ').unwrap_or((a, ""));
                let (pb, vb) = b.split_once(' ').unwrap_or((b, ""));
                let (va, vb) = (shown(va), shown(vb));
                return Some(if pa == pb {
                    format!("{at}: field {pa}: {want_is} {va}, {got_is} {vb}")
                } else {
                    format!("{at}: {want_is} field {pa} = {va}, {got_is} `{pb} {vb}` there")
                });
            }
            (Some(a), None) => return Some(format!("{at}: {got_is} nothing from field `{a}` on")),
            (None, Some(b)) => return Some(format!("{at}: {got_is} a field more: `{b}`")),
            (None, None) => unreachable!(),
        }
    }
}

/// Panics with every difference (the first 20 spelled out) when there is any.
fn report(what: &str, checked: usize, diffs: Vec<String>) {
    assert!(checked > 0, "{what}: nothing checked");
    if diffs.is_empty() {
        eprintln!("{what}: {checked} instances, every field the same");
        return;
    }
    let shown: Vec<&str> = diffs.iter().take(20).map(String::as_str).collect();
    panic!(
        "{what}: {} of {checked} instances differ:\n  {}",
        diffs.len(),
        shown.join("\n  ")
    );
}

/// Rust encodes, the peer decodes with lcm-gen's code and dumps every field.
fn peer_decodes(peer: &Peer) {
    let (samples, _) = corpus();
    let samples: Vec<&Sample> = samples.iter().filter(|s| !peer.skips(s.ty)).collect();
    let mut input = String::new();
    for s in &samples {
        let _ = writeln!(input, "{} {} {}", s.ty, s.index, hex(&s.bytes));
    }
    let output = peer.run("decode", &input);
    let mut blocks: HashMap<(String, usize), String> = HashMap::new();
    let mut current: Option<(String, usize)> = None;
    for l in output.lines() {
        if let Some(h) = l.strip_prefix("== ") {
            let (t, i) = h.split_once(' ').expect("== TYPE INDEX");
            let key = (t.to_owned(), i.parse().expect("an index"));
            blocks.insert(key.clone(), String::new());
            current = Some(key);
        } else {
            let key = current.as_ref().expect("a block header first");
            let b = blocks.get_mut(key).unwrap();
            b.push_str(l);
            b.push('\n');
        }
    }
    let mut diffs = Vec::new();
    for s in &samples {
        match blocks.get(&(s.ty.to_owned(), s.index)) {
            None => diffs.push(format!(
                "{} #{}: {} printed nothing",
                s.ty, s.index, peer.name
            )),
            Some(got) => diffs.extend(difference(
                s,
                &s.text,
                got,
                "Rust encoded",
                &format!("{} decoded", peer.name),
            )),
        }
    }
    report(
        &format!("{} decoding Rust's bytes", peer.name),
        samples.len(),
        diffs,
    );
}

/// The peer builds lcm-gen's objects from Rust's dumps and encodes them; Rust decodes.
fn peer_encodes(peer: &Peer) {
    let (samples, kinds) = corpus();
    let samples: Vec<&Sample> = samples.iter().filter(|s| !peer.skips(s.ty)).collect();
    let mut input = String::new();
    for s in &samples {
        let _ = writeln!(input, "== {} {}", s.ty, s.index);
        input.push_str(&s.text);
    }
    let output = peer.run("encode", &input);
    let mut encoded: HashMap<(&str, usize), &str> = HashMap::new();
    for l in output.lines() {
        let mut w = l.split(' ');
        let (t, i, h) = (w.next().unwrap(), w.next(), w.next());
        let i = i.and_then(|i| i.parse().ok()).expect("TYPE INDEX HEX");
        encoded.insert((t, i), h.expect("TYPE INDEX HEX"));
    }
    let mut diffs = Vec::new();
    for s in &samples {
        let Some(h) = encoded.get(&(s.ty, s.index)) else {
            diffs.push(format!(
                "{} #{}: {} encoded nothing",
                s.ty, s.index, peer.name
            ));
            continue;
        };
        let kind = &kinds[s.ty];
        match unhex(h).and_then(|b| (kind.redump)(&b)) {
            Err(e) => diffs.push(format!(
                "{} #{}: Rust cannot decode {}'s bytes: {e}",
                kind.ty, s.index, peer.name
            )),
            Ok(got) => diffs.extend(difference(
                s,
                &s.text,
                &got,
                &format!("{} was given", peer.name),
                "Rust decoded from its bytes",
            )),
        }
    }
    report(
        &format!("Rust decoding {}'s bytes", peer.name),
        samples.len(),
        diffs,
    );
}

#[test]
fn the_random_instances_have_edge_values() {
    let (samples, _) = corpus();
    let all: String = samples.iter().map(|s| s.text.as_str()).collect();
    for (what, needle) in [
        ("NaN", " nan\n"),
        ("a double +inf", " d:7ff0000000000000\n"),
        ("a double -inf", " d:fff0000000000000\n"),
        ("a double -0", " d:8000000000000000\n"),
        ("a float +inf", " f:7f800000\n"),
        ("a float -inf", " f:ff800000\n"),
        ("a subnormal float", " f:00000001\n"),
        ("an empty array", "num_joints 0\n"),
        ("an empty string", " s:\n"),
        ("a 4-byte UTF-8 character", "f09f9880"),
        ("a 3-byte UTF-8 character", "e282ac"),
        ("an array of 100 or more", "[100]"),
        ("the least int64_t", " -9223372036854775808\n"),
        ("the greatest int64_t", " 9223372036854775807\n"),
        ("the least int32_t", " -2147483648\n"),
        ("the least int8_t", " -128\n"),
        ("a byte 255", " 255\n"),
    ] {
        assert!(all.contains(needle), "no instance has {what} ({needle:?})");
    }
    // Per type: a type with floats has had a NaN and an infinity, one with strings a
    // non-ASCII character.
    let mut by_type: HashMap<&str, String> = HashMap::new();
    for s in samples {
        by_type.entry(s.ty).or_default().push_str(&s.text);
    }
    for (ty, text) in &by_type {
        let values: Vec<&str> = text
            .lines()
            .filter_map(|l| l.split_once(' '))
            .map(|(_, v)| v)
            .collect();
        if values
            .iter()
            .any(|v| v.starts_with("f:") || v.starts_with("d:"))
        {
            assert!(values.contains(&"nan"), "no {ty} has a NaN");
            let inf = [
                "f:7f800000",
                "f:ff800000",
                "d:7ff0000000000000",
                "d:fff0000000000000",
            ];
            assert!(
                values.iter().any(|v| inf.contains(v)),
                "no {ty} has an infinity"
            );
        }
        let strings: Vec<&str> = values.iter().filter_map(|v| v.strip_prefix("s:")).collect();
        if !strings.is_empty() {
            let wide = |h: &&str| (0..h.len()).step_by(2).any(|i| h.as_bytes()[i] >= b'8');
            assert!(strings.iter().any(wide), "no {ty} has a non-ASCII string");
        }
    }
    let longest = all
        .lines()
        .filter_map(|l| l.split_once(" s:"))
        .map(|(_, h)| h.len() / 2)
        .max()
        .unwrap();
    assert!(
        longest >= 1000,
        "the longest string has {longest} bytes only"
    );
    eprintln!(
        "{} instances, {} fields, longest string {longest} bytes",
        samples.len(),
        all.lines().count()
    );
}

#[test]
fn c_decodes_the_values_rust_encodes() {
    peer_decodes(&C);
}

#[test]
fn rust_decodes_the_values_c_encodes() {
    peer_encodes(&C);
}

#[test]
fn java_decodes_the_values_rust_encodes() {
    peer_decodes(&JAVA);
}

#[test]
fn rust_decodes_the_values_java_encodes() {
    peer_encodes(&JAVA);
}

#[test]
fn python_decodes_the_values_rust_encodes() {
    peer_decodes(&PYTHON);
}

#[test]
fn rust_decodes_the_values_python_encodes() {
    peer_encodes(&PYTHON);
}
