//! lcm-gen's fingerprints: the per-struct base hash and the recursive fingerprint.

use std::collections::HashMap;

use crate::ast::{Struct, TypeRef};

fn update(v: i64, c: u8) -> i64 {
    // lcm-gen adds a C `char`; identifiers and sizes are ASCII (< 128), so signedness is moot.
    ((v << 8) ^ (v >> 55)).wrapping_add(c as i8 as i64)
}

fn update_str(mut v: i64, s: &str) -> i64 {
    v = update(v, s.len() as u8);
    for b in s.bytes() {
        v = update(v, b);
    }
    v
}

/// The base hash lcm-gen computes from a struct's declaration (members only; names of the
/// struct and of nested types do not count).
pub fn base_hash(s: &Struct) -> u64 {
    let mut v: i64 = 0x12345678;
    for m in &s.members {
        v = update_str(v, &m.name);
        if let TypeRef::Primitive(p) = &m.ty {
            v = update_str(v, p.lcm_name());
        }
        v = update(v, m.dims.len() as u8);
        for d in &m.dims {
            let mode = matches!(d, crate::ast::Dim::Var(_)) as u8;
            v = update(v, mode);
            v = update_str(v, d.text());
        }
    }
    v as u64
}

/// The fingerprint: the base hash plus the fingerprints of the nested types (a type already
/// on the path counts 0, which cuts recursion), rotated left by one.
pub fn fingerprint(name: &str, structs: &HashMap<String, &Struct>) -> u64 {
    fn rec(name: &str, structs: &HashMap<String, &Struct>, parents: &mut Vec<String>) -> u64 {
        if parents.iter().any(|p| p == name) {
            return 0;
        }
        let s = structs[name];
        let mut h = base_hash(s);
        parents.push(name.to_owned());
        for m in &s.members {
            if let TypeRef::Struct(child) = &m.ty {
                h = h.wrapping_add(rec(child, structs, parents));
            }
        }
        parents.pop();
        h.rotate_left(1)
    }
    rec(name, structs, &mut Vec::new())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parse::parse_file;

    fn fp_of(files: &[&str], name: &str) -> (u64, u64) {
        let all: Vec<Struct> = files
            .iter()
            .flat_map(|src| parse_file("t.lcm", src).unwrap())
            .collect();
        let map: HashMap<String, &Struct> = all.iter().map(|s| (s.full_name(), s)).collect();
        (base_hash(map[name]), fingerprint(name, &map))
    }

    // Golden values produced by lcm-gen 1.3.1 and 1.5.3.
    #[test]
    fn lcm_gen_golden_vectors() {
        assert_eq!(
            fp_of(&["struct tiny_t { int32_t a; }"], "tiny_t"),
            (0x6992dce02262360e, 0xd325b9c044c46c1c)
        );
        assert_eq!(
            fp_of(&["struct empty_t { }"], "empty_t"),
            (0x12345678, 0x2468acf0)
        );
        let point = "package demo; struct point_t { double x; double y; }";
        assert_eq!(
            fp_of(&[point], "demo.point_t"),
            (0xd259512e30b44885, 0xa4b2a25c6168910b)
        );
        let sample = "package demo; struct sample_t {
            const int8_t MAGIC = 7; const int8_t OTHER = 0x10; const double PI = 3.14;
            int64_t utime; int8_t i8; int16_t i16; int32_t i32; float f; double d; string name;
            boolean ok; byte raw[4]; int32_t n; byte blob[n]; double ranges[n]; boolean flags[2][n];
            string names[n]; point_t p; point_t pts[n]; point_t grid[2][3]; }";
        assert_eq!(
            fp_of(&[point, sample], "demo.sample_t"),
            (0x9c8d320bfb075a97, 0x154a32423e821b71)
        );
        let node = "package lcmtest; struct node_t { int32_t num_children; lcmtest.node_t children[num_children]; }";
        assert_eq!(
            fp_of(&[node], "lcmtest.node_t"),
            (0x98ff4a363aeb7273, 0x31fe946c75d6e4e7)
        );
        let arrays = "package lcmtest3; struct arrays_t { const int8_t dim = 0x0a; int8_t arr[dim]; int16_t m[2][dim]; }";
        assert_eq!(
            fp_of(&[arrays], "lcmtest3.arrays_t"),
            (0xc3b21d2e38b0bec0, 0x87643a5c71617d81)
        );
        let xyz = "struct p3_t { double x; double y; double z; }";
        assert_eq!(fp_of(&[xyz], "p3_t").0, 0x573f2fdd2f76508f);
    }

    #[test]
    fn size_text_counts_not_value() {
        let a = fp_of(&["struct a_t { int8_t x[16]; }"], "a_t");
        let b = fp_of(&["struct a_t { int8_t x[0x10]; }"], "a_t");
        assert_ne!(a, b);
    }
}
