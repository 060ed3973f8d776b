//! A generator of Rust code from LCM type definitions (`.lcm` files), byte-compatible with
//! `lcm-gen`: the same encoding, the same fingerprints.
//!
//! ```no_run
//! let files = lcmgen::find_lcm_files("lcmtypes/lcm").unwrap();
//! let types = lcmgen::TypeSet::from_files(&files).unwrap();
//! let rust = lcmgen::rust::generate(&types, &lcmgen::rust::Options::default());
//! std::fs::write("types.rs", rust).unwrap();
//! ```
//!
//! The generated code depends on the `lcm` crate (the `Message` trait and its codec), and,
//! behind features of the crate that includes it, on `serde` + `serde-big-array` (`serde`),
//! `serde_json` (`json`: every type's `to_json` and `JSON_SCHEMA`, members in declaration order
//! when serde_json's `preserve_order` is on) and nothing more for `random`.

pub mod ast;
pub mod hash;
pub mod parse;
pub mod rust;
pub mod schema;

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use ast::{Dim, Primitive, Struct, TypeRef};
pub use parse::Error;

/// A complete, checked set of types: every referenced type is defined, names are unique, and
/// no struct contains itself except through a variable-length array.
#[derive(Debug, Clone)]
pub struct TypeSet {
    structs: BTreeMap<String, Struct>,
}

fn set_error(file: &str, message: String) -> Error {
    Error {
        file: file.to_owned(),
        line: 0,
        message,
    }
}

impl TypeSet {
    /// Parses and checks the given files.
    pub fn from_files(files: &[PathBuf]) -> Result<TypeSet, Error> {
        let mut sources = Vec::new();
        for f in files {
            let name = f.display().to_string();
            let src = std::fs::read_to_string(f)
                .map_err(|e| set_error(&name, format!("cannot read: {e}")))?;
            sources.push((name, src));
        }
        TypeSet::from_sources(sources.iter().map(|(n, s)| (n.as_str(), s.as_str())))
    }

    /// Parses and checks `(file name, source)` pairs.
    pub fn from_sources<'a>(
        sources: impl IntoIterator<Item = (&'a str, &'a str)>,
    ) -> Result<TypeSet, Error> {
        let mut structs = BTreeMap::new();
        for (file, src) in sources {
            for s in parse::parse_file(file, src)? {
                let name = s.full_name();
                if let Some(prev) = structs.get(&name) {
                    let prev: &Struct = prev;
                    return Err(set_error(
                        file,
                        format!("{name} is defined twice (also in {})", prev.file),
                    ));
                }
                structs.insert(name, s);
            }
        }
        let set = TypeSet { structs };
        set.check()?;
        Ok(set)
    }

    fn check(&self) -> Result<(), Error> {
        for s in self.structs.values() {
            for m in &s.members {
                if let TypeRef::Struct(t) = &m.ty {
                    if !self.structs.contains_key(t) {
                        return Err(set_error(
                            &s.file,
                            format!("{}.{} has unknown type {t}", s.full_name(), m.name),
                        ));
                    }
                }
            }
        }
        // A struct may reach itself only through a variable-length array.
        for name in self.structs.keys() {
            let mut stack = vec![name.clone()];
            let mut seen = std::collections::HashSet::new();
            while let Some(cur) = stack.pop() {
                for m in &self.structs[&cur].members {
                    if m.dims.iter().any(|d| matches!(d, Dim::Var(_))) {
                        continue;
                    }
                    if let TypeRef::Struct(t) = &m.ty {
                        if t == name {
                            let s = &self.structs[name];
                            return Err(set_error(
                                &s.file,
                                format!(
                                    "{name} contains itself by value (through {cur}.{}); only a variable-length array may",
                                    m.name
                                ),
                            ));
                        }
                        if seen.insert(t.clone()) {
                            stack.push(t.clone());
                        }
                    }
                }
            }
        }
        for s in self.structs.values() {
            for m in &s.members {
                let fixed: Vec<usize> = m
                    .dims
                    .iter()
                    .map(|d| match d {
                        Dim::Const { value, .. } => *value,
                        Dim::Var(_) => 0,
                    })
                    .collect();
                if fixed.iter().skip(1).any(|v| *v > 32) {
                    return Err(set_error(
                        &s.file,
                        format!(
                            "{}.{}: an inner fixed dimension above 32 is not supported (make it the outer one, or variable)",
                            s.full_name(),
                            m.name
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Every struct, by full name, in name order.
    pub fn structs(&self) -> impl Iterator<Item = &Struct> {
        self.structs.values()
    }

    /// A struct by full name.
    pub fn get(&self, name: &str) -> Option<&Struct> {
        self.structs.get(name)
    }

    fn by_name(&self) -> HashMap<String, &Struct> {
        self.structs.iter().map(|(k, v)| (k.clone(), v)).collect()
    }

    /// lcm-gen's fingerprint of a struct (the first 8 bytes of its messages).
    pub fn fingerprint(&self, name: &str) -> u64 {
        hash::fingerprint(name, &self.by_name())
    }

    /// The smallest encoded body of a struct (variable arrays empty, strings empty).
    pub fn min_body_size(&self, name: &str) -> usize {
        let s = &self.structs[name];
        s.members
            .iter()
            .map(|m| self.min_size(&m.ty, &m.dims))
            .sum()
    }

    /// The smallest encoding of a member of type `ty` with dimensions `dims`.
    pub fn min_size(&self, ty: &TypeRef, dims: &[Dim]) -> usize {
        let mut count = 1usize;
        for d in dims {
            match d {
                Dim::Const { value, .. } => count = count.saturating_mul(*value),
                Dim::Var(_) => return 0,
            }
        }
        let elem = match ty {
            TypeRef::Primitive(Primitive::String) => 5,
            TypeRef::Primitive(p) => p.fixed_size().unwrap_or(0),
            TypeRef::Struct(t) => self.min_body_size(t),
        };
        count.saturating_mul(elem)
    }
}

/// Every `.lcm` file below `dir`, sorted.
pub fn find_lcm_files(dir: impl AsRef<Path>) -> std::io::Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    let mut stack = vec![dir.as_ref().to_owned()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d)? {
            let p = entry?.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e == "lcm") {
                out.push(p);
            }
        }
    }
    out.sort();
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn set_checks() {
        let ok = TypeSet::from_sources([
            (
                "a.lcm",
                "package p; struct a_t { b_t b; int32_t n; a_t kids[n]; }",
            ),
            ("b.lcm", "package p; struct b_t { double x; }"),
        ])
        .unwrap();
        assert_eq!(ok.min_body_size("p.a_t"), 8 + 4);
        let errs = [
            ("package p; struct a_t { c_t c; }", "unknown type p.c_t"),
            ("package p; struct a_t { a_t me; }", "contains itself"),
            ("package p; struct a_t { a_t me[2]; }", "contains itself"),
            (
                "package p; struct a_t { int32_t n; double x[n][40]; }",
                "inner fixed",
            ),
        ];
        for (src, want) in errs {
            let e = TypeSet::from_sources([("x.lcm", src)])
                .unwrap_err()
                .to_string();
            assert!(e.contains(want), "{src}: {e}");
        }
        let twice =
            TypeSet::from_sources([("x.lcm", "struct a_t { }"), ("y.lcm", "struct a_t { }")])
                .unwrap_err();
        assert!(twice.to_string().contains("defined twice"));
    }
}
