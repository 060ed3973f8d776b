//! The Rust emitter.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write;

use crate::ast::{ConstValue, Dim, Member, Primitive, Struct, TypeRef};
use crate::TypeSet;

/// Whether a piece of generated code is emitted, and under which condition.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Gate {
    /// Not emitted.
    Never,
    /// Emitted behind the including crate's feature of that name (`serde`, `json`, `random`).
    Feature,
    /// Emitted unconditionally.
    Always,
}

impl Gate {
    fn attr(self, feature: &str) -> Option<String> {
        match self {
            Gate::Never => None,
            Gate::Feature => Some(format!("#[cfg(feature = \"{feature}\")]\n")),
            Gate::Always => Some(String::new()),
        }
    }
}

/// What to emit besides the types.
#[derive(Debug, Clone)]
pub struct Options {
    /// Emit `TYPES` (name and fingerprint of every type), and with JSON `decode_json` (any
    /// message to JSON by its fingerprint) and `json_schema` (a type's schema by name).
    pub registry: bool,
    /// serde `Serialize`/`Deserialize` derives (needs `serde` and `serde-big-array`); the same
    /// gate, under the feature `json`, emits every type's `to_json` and `JSON_SCHEMA` and the
    /// function `json_float` (needs `serde_json`).
    pub serde: Gate,
    /// `lcm::Random` impls (random instances for tests).
    pub random: Gate,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            registry: true,
            serde: Gate::Feature,
            random: Gate::Feature,
        }
    }
}

const KEYWORDS: &[&str] = &[
    "as", "async", "await", "break", "const", "continue", "dyn", "else", "enum", "false", "fn",
    "for", "if", "impl", "in", "let", "loop", "match", "mod", "move", "mut", "pub", "ref",
    "return", "static", "struct", "trait", "true", "type", "unsafe", "use", "where", "while",
    "abstract", "become", "box", "do", "final", "gen", "macro", "override", "priv", "try",
    "typeof", "unsized", "virtual", "yield",
];

/// A Rust identifier for an LCM name (raw identifiers for keywords).
pub fn ident(name: &str) -> String {
    match name {
        "self" | "Self" | "super" | "crate" | "extern" | "_" => format!("{name}_"),
        n if KEYWORDS.contains(&n) => format!("r#{n}"),
        n => n.to_owned(),
    }
}

/// The Rust type name of an LCM struct name: `node_status_t` becomes `NodeStatusT`.
pub fn type_name(name: &str) -> String {
    let mut out = String::new();
    for part in name.split('_').filter(|p| !p.is_empty()) {
        let mut c = part.chars();
        if let Some(f) = c.next() {
            out.extend(f.to_uppercase());
            out.push_str(c.as_str());
        }
    }
    if out.is_empty() || out.starts_with(|c: char| c.is_ascii_digit()) {
        out.insert(0, 'T');
    }
    out
}

fn split_full(full: &str) -> (&str, &str) {
    match full.rfind('.') {
        Some(i) => (&full[..i], &full[i + 1..]),
        None => ("", full),
    }
}

/// Path from a module of package `from` to the type `full`.
fn type_path(from: &str, full: &str) -> String {
    let (pkg, name) = split_full(full);
    let depth = if from.is_empty() {
        0
    } else {
        from.split('.').count()
    };
    let mut p = "super::".repeat(depth);
    for part in pkg.split('.').filter(|s| !s.is_empty()) {
        p.push_str(&ident(part));
        p.push_str("::");
    }
    p.push_str(&type_name(name));
    p
}

fn prim_rust(p: Primitive) -> &'static str {
    match p {
        Primitive::Int8 => "i8",
        Primitive::Int16 => "i16",
        Primitive::Int32 => "i32",
        Primitive::Int64 => "i64",
        Primitive::Float => "f32",
        Primitive::Double => "f64",
        Primitive::String => "String",
        Primitive::Boolean => "bool",
        Primitive::Byte => "u8",
    }
}

/// Numeric types with a bulk slice codec in `lcm::Encoder`/`lcm::Decoder`.
fn bulk(p: Primitive) -> Option<&'static str> {
    match p {
        Primitive::Int8 => Some("i8"),
        Primitive::Int16 => Some("i16"),
        Primitive::Int32 => Some("i32"),
        Primitive::Int64 => Some("i64"),
        Primitive::Float => Some("f32"),
        Primitive::Double => Some("f64"),
        Primitive::Byte => Some("u8"),
        _ => None,
    }
}

struct Ctx<'a> {
    set: &'a TypeSet,
    pkg: &'a str,
}

impl Ctx<'_> {
    fn elem_type(&self, ty: &TypeRef) -> String {
        match ty {
            TypeRef::Primitive(p) => prim_rust(*p).to_owned(),
            TypeRef::Struct(t) => type_path(self.pkg, t),
        }
    }

    fn rust_type(&self, ty: &TypeRef, dims: &[Dim]) -> String {
        let mut t = self.elem_type(ty);
        for d in dims.iter().rev() {
            t = match d {
                Dim::Const { value, .. } => format!("[{t}; {value}]"),
                Dim::Var(_) => format!("Vec<{t}>"),
            };
        }
        t
    }

    fn default_expr(&self, ty: &TypeRef, dims: &[Dim]) -> String {
        match dims.first() {
            None => match ty {
                TypeRef::Primitive(Primitive::String) => "String::new()".into(),
                TypeRef::Primitive(Primitive::Boolean) => "false".into(),
                TypeRef::Primitive(Primitive::Float | Primitive::Double) => "0.0".into(),
                TypeRef::Primitive(_) => "0".into(),
                TypeRef::Struct(_) => "Default::default()".into(),
            },
            Some(Dim::Var(_)) => "Vec::new()".into(),
            Some(Dim::Const { .. }) => {
                format!(
                    "core::array::from_fn(|_| {})",
                    self.default_expr(ty, &dims[1..])
                )
            }
        }
    }

    /// A zero literal of a numeric type with fixed dimensions only.
    fn zero_literal(p: Primitive, dims: &[Dim]) -> String {
        let mut t = match p {
            Primitive::Float => "0f32".to_owned(),
            Primitive::Double => "0f64".to_owned(),
            other => format!("0{}", prim_rust(other)),
        };
        for d in dims.iter().rev() {
            if let Dim::Const { value, .. } = d {
                t = format!("[{t}; {value}]");
            }
        }
        t
    }

    /// `expr` is a place (`self.f`) when `is_ref` is false, a reference (`x0`) when true.
    fn size_expr(
        &self,
        expr: &str,
        is_ref: bool,
        ty: &TypeRef,
        dims: &[Dim],
        depth: usize,
    ) -> String {
        let by_ref = if is_ref {
            expr.to_owned()
        } else {
            format!("&{expr}")
        };
        if dims.is_empty() {
            return match ty {
                TypeRef::Primitive(Primitive::String) => format!("4 + {expr}.len() + 1"),
                TypeRef::Primitive(p) => p.fixed_size().expect("fixed").to_string(),
                TypeRef::Struct(_) => format!("lcm::Message::body_size({by_ref})"),
            };
        }
        let rest_fixed: Option<usize> = dims[1..].iter().try_fold(1usize, |acc, d| match d {
            Dim::Const { value, .. } => Some(acc * value),
            Dim::Var(_) => None,
        });
        if let (TypeRef::Primitive(p), Some(inner)) = (ty, rest_fixed) {
            if let Some(n) = p.fixed_size() {
                return format!("{expr}.len() * {}", inner * n);
            }
        }
        let x = format!("x{depth}");
        // A table of fixed-size numbers (rows of a variable length) is sized from its first
        // row, as lcm-gen's C sizes it from the declared lengths: a message encodes only when
        // every row has the declared length, and a walk over a thousand rows would cost as
        // much as copying them.
        if let TypeRef::Primitive(p) = ty {
            if p.fixed_size().is_some() && dims.len() == 2 {
                return format!(
                    "{expr}.len().saturating_mul({expr}.first().map_or(0, |{x}| {}))",
                    self.size_expr(&x, true, ty, &dims[1..], depth + 1)
                );
            }
        }
        format!(
            "{expr}.iter().map(|{x}| {}).sum::<usize>()",
            self.size_expr(&x, true, ty, &dims[1..], depth + 1)
        )
    }

    fn flattened(expr: &str, k: usize, mutable: bool) -> String {
        let mut s = expr.to_owned();
        for _ in 0..k {
            s = if mutable {
                format!("{s}.as_flattened_mut()")
            } else {
                format!("{s}.as_flattened()")
            };
        }
        s
    }

    /// Statements encoding `expr`: a place (`self.f`) when `is_ref` is false, a reference
    /// (`x0`) when true.
    fn encode(
        &self,
        out: &mut String,
        expr: &str,
        is_ref: bool,
        ty: &TypeRef,
        dims: &[Dim],
        depth: usize,
    ) {
        let pad = "        ".to_owned() + &"    ".repeat(depth);
        let by_ref = if is_ref {
            expr.to_owned()
        } else {
            format!("&{expr}")
        };
        let by_val = if is_ref {
            format!("*{expr}")
        } else {
            expr.to_owned()
        };
        if dims.is_empty() {
            let stmt = match ty {
                TypeRef::Primitive(Primitive::String) => format!("e.put_str({by_ref})?;"),
                TypeRef::Primitive(Primitive::Boolean) => format!("e.put_bool({by_val});"),
                TypeRef::Primitive(p) => {
                    format!("e.put_{}({by_val});", bulk(*p).expect("numeric"))
                }
                TypeRef::Struct(_) => format!("lcm::Message::encode_body({by_ref}, e)?;"),
            };
            let _ = writeln!(out, "{pad}{stmt}");
            return;
        }
        if let Dim::Var(n) = &dims[0] {
            let field = format!("self.{}", ident(n));
            let _ = writeln!(
                out,
                "{pad}if {expr}.len() as i64 != {field} as i64 {{ return Err(lcm::EncodeError::SizeMismatch {{ field: {n:?}, declared: {field} as i64, actual: {expr}.len() }}); }}"
            );
        }
        // Rows of a variable length (a table: trajectories' positions): checked and written
        // in one pass.
        if let (TypeRef::Primitive(p), [_, Dim::Var(m)]) = (ty, dims) {
            if let Some(b) = bulk(*p) {
                let field = format!("self.{}", ident(m));
                let _ = writeln!(
                    out,
                    "{pad}e.put_{b}_rows({by_ref}, {field} as i64, {m:?})?;"
                );
                return;
            }
        }
        let rest_all_fixed = dims[1..].iter().all(|d| matches!(d, Dim::Const { .. }));
        if let (TypeRef::Primitive(p), true) = (ty, rest_all_fixed) {
            if let Some(b) = bulk(*p) {
                let k = dims.len() - 1;
                let flat = if k == 0 {
                    by_ref
                } else {
                    Self::flattened(expr, k, false)
                };
                let _ = writeln!(out, "{pad}e.put_{b}_slice({flat});");
                return;
            }
        }
        let x = format!("x{depth}");
        let _ = writeln!(out, "{pad}for {x} in {expr}.iter() {{");
        self.encode(out, &x, true, ty, &dims[1..], depth + 1);
        let _ = writeln!(out, "{pad}}}");
    }

    /// An expression decoding a value of this type (locals `f_<member>` hold size members).
    fn decode(&self, ty: &TypeRef, dims: &[Dim]) -> String {
        if dims.is_empty() {
            return match ty {
                TypeRef::Primitive(Primitive::String) => "d.get_string()?".into(),
                TypeRef::Primitive(Primitive::Boolean) => "d.get_bool()?".into(),
                TypeRef::Primitive(p) => format!("d.get_{}()?", bulk(*p).expect("numeric")),
                TypeRef::Struct(t) => format!(
                    "<{} as lcm::Message>::decode_body(d)?",
                    type_path(self.pkg, t)
                ),
            };
        }
        let len = match &dims[0] {
            Dim::Const { value, .. } => value.to_string(),
            Dim::Var(n) => format!(
                "d.check_len(f_{n} as i64, {})?",
                self.min_size_expr(ty, &dims[1..])
            ),
        };
        let rest_all_fixed = dims[1..].iter().all(|d| matches!(d, Dim::Const { .. }));
        if let (TypeRef::Primitive(p), true) = (ty, rest_all_fixed) {
            if let Some(b) = bulk(*p) {
                let k = dims.len() - 1;
                return match &dims[0] {
                    Dim::Var(_) if k == 0 && *p == Primitive::Byte => {
                        format!("d.take({len})?.to_vec()")
                    }
                    Dim::Var(_) => format!(
                        "{{ let n = {len}; let mut v = vec![{}; n]; d.get_{b}_into({})?; v }}",
                        Self::zero_literal(*p, &dims[1..]),
                        if k == 0 {
                            "&mut v".to_owned()
                        } else {
                            Self::flattened("v", k, true)
                        }
                    ),
                    Dim::Const { .. } => format!(
                        "{{ let mut v = {}; d.get_{b}_into({})?; v }}",
                        Self::zero_literal(*p, dims),
                        if k == 0 {
                            "&mut v".to_owned()
                        } else {
                            Self::flattened("v", k, true)
                        }
                    ),
                };
            }
        }
        let inner = self.decode(ty, &dims[1..]);
        match &dims[0] {
            Dim::Var(_) => format!(
                "{{ let n = {len}; let mut v = Vec::with_capacity(n); for _ in 0..n {{ v.push({inner}); }} v }}"
            ),
            Dim::Const { value, .. } => format!(
                "{{ let mut v = Vec::with_capacity({value}); for _ in 0..{value} {{ v.push({inner}); }} match <[_; {value}]>::try_from(v) {{ Ok(a) => a, Err(_) => unreachable!() }} }}"
            ),
        }
    }

    /// The smallest encoding of one element with these inner dimensions, as an expression:
    /// inner variable sizes are already decoded into locals.
    fn min_size_expr(&self, ty: &TypeRef, dims: &[Dim]) -> String {
        let scalar = self.set.min_size(ty, &[]);
        let mut fixed = scalar;
        let mut vars = Vec::new();
        for d in dims {
            match d {
                Dim::Const { value, .. } => fixed = fixed.saturating_mul(*value),
                Dim::Var(n) => vars.push(format!("(f_{n}.max(0) as usize)")),
            }
        }
        let mut e = fixed.to_string();
        for v in vars {
            e = format!("{e}usize.saturating_mul{v}");
        }
        e
    }

    /// An expression giving the JSON value of `expr`: a place (`self.f`) when `is_ref` is
    /// false, a reference (`x0`) when true.
    fn json_expr(
        &self,
        expr: &str,
        is_ref: bool,
        ty: &TypeRef,
        dims: &[Dim],
        depth: usize,
    ) -> String {
        let by_val = if is_ref {
            format!("*{expr}")
        } else {
            expr.to_owned()
        };
        if dims.is_empty() {
            return match ty {
                TypeRef::Primitive(Primitive::String) => {
                    format!("serde_json::Value::from({expr}.as_str())")
                }
                TypeRef::Primitive(Primitive::Boolean) => {
                    format!("serde_json::Value::Bool({by_val})")
                }
                TypeRef::Primitive(Primitive::Float | Primitive::Double) => {
                    format!("{}(f64::from({by_val}))", self.json_float_path())
                }
                TypeRef::Primitive(_) => format!("serde_json::Value::from({by_val})"),
                TypeRef::Struct(_) => format!("{expr}.to_json()"),
            };
        }
        let x = format!("x{depth}");
        format!(
            "serde_json::Value::Array({expr}.iter().map(|{x}| {}).collect())",
            self.json_expr(&x, true, ty, &dims[1..], depth + 1)
        )
    }

    /// Path from this package's module to the generated `json_float`.
    fn json_float_path(&self) -> String {
        let depth = if self.pkg.is_empty() {
            0
        } else {
            self.pkg.split('.').count()
        };
        format!("{}json_float", "super::".repeat(depth))
    }

    fn random_expr(&self, ty: &TypeRef, dims: &[Dim]) -> String {
        match dims.first() {
            None => match ty {
                TypeRef::Primitive(Primitive::String) => "rng.string()".into(),
                TypeRef::Primitive(Primitive::Boolean) => "rng.bool()".into(),
                TypeRef::Primitive(Primitive::Float) => "rng.f32()".into(),
                TypeRef::Primitive(Primitive::Double) => "rng.f64()".into(),
                TypeRef::Primitive(p) => {
                    let t = prim_rust(*p);
                    let bits: u32 = t[1..].parse().expect("an integer type");
                    format!("rng.int({bits}) as {t}")
                }
                TypeRef::Struct(t) => {
                    format!("<{} as lcm::Random>::random(rng)", type_path(self.pkg, t))
                }
            },
            Some(Dim::Var(n)) => format!(
                "(0..f_{n} as usize).map(|_| {}).collect::<Vec<_>>()",
                self.random_expr(ty, &dims[1..])
            ),
            Some(Dim::Const { .. }) => format!(
                "core::array::from_fn(|_| {})",
                self.random_expr(ty, &dims[1..])
            ),
        }
    }
}

fn doc_lines(out: &mut String, pad: &str, doc: Option<&str>, fallback: &str) {
    let text = doc.unwrap_or(fallback);
    for line in text.lines() {
        let line = line.trim_end();
        if line.is_empty() {
            let _ = writeln!(out, "{pad}///");
        } else {
            let _ = writeln!(out, "{pad}/// {line}");
        }
    }
}

fn sequence_expr(set: &TypeSet, s: &Struct) -> Option<String> {
    let is_seq = |m: &Member| {
        m.name == "sequence" && m.dims.is_empty() && m.ty == TypeRef::Primitive(Primitive::Int64)
    };
    if s.members.iter().any(is_seq) {
        return Some("self.sequence".into());
    }
    let header = s
        .members
        .iter()
        .find(|m| m.name == "header" && m.dims.is_empty())?;
    let TypeRef::Struct(t) = &header.ty else {
        return None;
    };
    set.get(t)?
        .members
        .iter()
        .any(is_seq)
        .then(|| "self.header.sequence".into())
}

fn emit_struct(out: &mut String, set: &TypeSet, s: &Struct, opts: &Options) {
    let ctx = Ctx {
        set,
        pkg: &s.package,
    };
    let full = s.full_name();
    let name = type_name(&s.name);
    let size_vars: BTreeSet<&str> = s
        .members
        .iter()
        .flat_map(|m| m.dims.iter())
        .filter_map(|d| match d {
            Dim::Var(n) => Some(n.as_str()),
            Dim::Const { .. } => None,
        })
        .collect();

    // The struct.
    doc_lines(out, "", s.doc.as_deref(), &format!("LCM type `{full}`."));
    let _ = writeln!(out, "///\n/// LCM type `{full}`.");
    let _ = writeln!(out, "#[derive(Debug, Clone, PartialEq)]");
    let serde_attr = |inner: &str| match opts.serde {
        Gate::Never => None,
        Gate::Feature => Some(format!("#[cfg_attr(feature = \"serde\", {inner})]")),
        Gate::Always => Some(format!("#[{inner}]")),
    };
    if let Some(a) = serde_attr("derive(serde::Serialize, serde::Deserialize)") {
        let _ = writeln!(out, "{a}");
    }
    let _ = writeln!(out, "#[allow(non_snake_case)]\npub struct {name} {{");
    for m in &s.members {
        let fallback = if size_vars.contains(m.name.as_str()) {
            format!("Number of elements of the arrays sized by `{}`.", m.name)
        } else {
            format!("Member `{}`.", m.name)
        };
        doc_lines(out, "    ", m.doc.as_deref(), &fallback);
        if let Some(Dim::Const { value, .. }) = m.dims.first() {
            if *value > 32 {
                if let Some(a) = serde_attr("serde(with = \"serde_big_array::BigArray\")") {
                    let _ = writeln!(out, "    {a}");
                }
            }
        }
        let _ = writeln!(
            out,
            "    pub {}: {},",
            ident(&m.name),
            ctx.rust_type(&m.ty, &m.dims)
        );
    }
    let _ = writeln!(out, "}}\n");

    // Constants and the base hash.
    let _ = writeln!(out, "#[allow(non_upper_case_globals)]\nimpl {name} {{");
    for c in &s.consts {
        doc_lines(
            out,
            "    ",
            c.doc.as_deref(),
            &format!("Constant `{}` (`{}`).", c.name, c.text),
        );
        let value = match c.value {
            ConstValue::Int(v) => v.to_string(),
            ConstValue::Float(v) if c.ty == Primitive::Float => format!("{:?}", v as f32),
            ConstValue::Float(v) => format!("{v:?}"),
        };
        let _ = writeln!(
            out,
            "    pub const {}: {} = {value};",
            ident(&c.name),
            prim_rust(c.ty)
        );
    }
    let _ = writeln!(
        out,
        "    /// lcm-gen's base hash of the declaration (before nested types are folded in).\n    pub const LCM_BASE_HASH: u64 = {:#018x};",
        crate::hash::base_hash(s)
    );
    let _ = writeln!(out, "}}\n");

    // Default.
    let _ = writeln!(
        out,
        "impl Default for {name} {{\n    fn default() -> Self {{\n        Self {{"
    );
    for m in &s.members {
        let _ = writeln!(
            out,
            "            {}: {},",
            ident(&m.name),
            ctx.default_expr(&m.ty, &m.dims)
        );
    }
    let _ = writeln!(out, "        }}\n    }}\n}}\n");

    // Message.
    let _ = writeln!(
        out,
        "#[allow(non_snake_case)]\nimpl lcm::Message for {name} {{"
    );
    let _ = writeln!(
        out,
        "    const FINGERPRINT: u64 = {:#018x};\n    const TYPE_NAME: &'static str = {full:?};\n",
        set.fingerprint(&full)
    );
    let _ = writeln!(out, "    fn body_size(&self) -> usize {{");
    let sizes: Vec<String> = s
        .members
        .iter()
        .map(|m| {
            ctx.size_expr(
                &format!("self.{}", ident(&m.name)),
                false,
                &m.ty,
                &m.dims,
                0,
            )
        })
        .collect();
    let _ = writeln!(
        out,
        "        0{}\n    }}\n",
        sizes
            .iter()
            .map(|x| format!("\n            + {x}"))
            .collect::<String>()
    );
    let _ = writeln!(
        out,
        "    fn encode_body(&self, e: &mut lcm::Encoder<'_>) -> Result<(), lcm::EncodeError> {{"
    );
    if s.members.is_empty() {
        let _ = writeln!(out, "        let _ = e;");
    }
    for m in &s.members {
        ctx.encode(
            out,
            &format!("self.{}", ident(&m.name)),
            false,
            &m.ty,
            &m.dims,
            0,
        );
    }
    let _ = writeln!(out, "        Ok(())\n    }}\n");
    let _ = writeln!(
        out,
        "    fn decode_body(d: &mut lcm::Decoder<'_>) -> Result<Self, lcm::DecodeError> {{"
    );
    if s.members.is_empty() {
        let _ = writeln!(out, "        let _ = d;");
    }
    for m in &s.members {
        let _ = writeln!(
            out,
            "        let f_{} = {};",
            m.name,
            ctx.decode(&m.ty, &m.dims)
        );
    }
    let _ = writeln!(out, "        Ok(Self {{");
    for m in &s.members {
        let _ = writeln!(out, "            {}: f_{},", ident(&m.name), m.name);
    }
    let _ = writeln!(out, "        }})\n    }}");
    if let Some(seq) = sequence_expr(set, s) {
        let _ = writeln!(
            out,
            "\n    fn sequence(&self) -> Option<i64> {{\n        Some({seq})\n    }}"
        );
    }
    let _ = writeln!(out, "}}\n");

    // JSON, and its schema.
    if let Some(gate) = opts.serde.attr("json") {
        let schema = crate::schema::json_schema(set, &full).to_text();
        let _ = writeln!(out, "{gate}#[allow(non_snake_case)]\nimpl {name} {{");
        let _ = writeln!(
            out,
            "    /// The JSON Schema (draft 2020-12) of [`Self::to_json`]'s value.\n    pub const JSON_SCHEMA: &'static str = {schema:?};\n"
        );
        let float = ctx.json_float_path();
        let _ = writeln!(
            out,
            "    /// The message as a JSON object: its members in declaration order (with serde_json's\n    /// `preserve_order`), numbers as numbers, and floats that are NaN or infinite as the\n    /// strings `\"NaN\"`, `\"inf\"`, `\"-inf\"` ([`json_float`]({float})).\n    pub fn to_json(&self) -> serde_json::Value {{"
        );
        if s.members.is_empty() {
            let _ = writeln!(
                out,
                "        serde_json::Value::Object(serde_json::Map::new())"
            );
        } else {
            let _ = writeln!(
                out,
                "        let mut m = serde_json::Map::with_capacity({});",
                s.members.len()
            );
            for m in &s.members {
                let _ = writeln!(
                    out,
                    "        m.insert({:?}.to_owned(), {});",
                    m.name,
                    ctx.json_expr(
                        &format!("self.{}", ident(&m.name)),
                        false,
                        &m.ty,
                        &m.dims,
                        0
                    )
                );
            }
            let _ = writeln!(out, "        serde_json::Value::Object(m)");
        }
        let _ = writeln!(out, "    }}\n}}\n");
    }

    // Random instances, for tests.
    let Some(gate) = opts.random.attr("random") else {
        return;
    };
    let _ = writeln!(
        out,
        "{gate}#[allow(non_snake_case)]\nimpl lcm::Random for {name} {{"
    );
    let _ = writeln!(out, "    fn random(rng: &mut lcm::Rng) -> Self {{");
    if s.members.is_empty() {
        let _ = writeln!(out, "        let _ = rng;");
    }
    for m in &s.members {
        let expr = if size_vars.contains(m.name.as_str()) {
            format!("rng.size() as {}", ctx.elem_type(&m.ty))
        } else {
            ctx.random_expr(&m.ty, &m.dims)
        };
        let _ = writeln!(out, "        let f_{} = {expr};", m.name);
    }
    let _ = writeln!(out, "        Self {{");
    for m in &s.members {
        let _ = writeln!(out, "            {}: f_{},", ident(&m.name), m.name);
    }
    let _ = writeln!(out, "        }}\n    }}\n}}\n");
}

#[derive(Default)]
struct ModTree<'a> {
    structs: Vec<&'a Struct>,
    children: BTreeMap<String, ModTree<'a>>,
}

fn emit_tree(out: &mut String, set: &TypeSet, tree: &ModTree<'_>, pkg: &str, opts: &Options) {
    for s in &tree.structs {
        emit_struct(out, set, s, opts);
    }
    for (name, child) in &tree.children {
        let sub = if pkg.is_empty() {
            name.clone()
        } else {
            format!("{pkg}.{name}")
        };
        let _ = writeln!(out, "/// LCM package `{sub}`.\npub mod {} {{", ident(name));
        emit_tree(out, set, child, &sub, opts);
        let _ = writeln!(out, "}}");
    }
}

/// Generates the Rust code of every type of `set`: one module per package.
pub fn generate(set: &TypeSet, opts: &Options) -> String {
    let mut tree = ModTree::default();
    for s in set.structs() {
        let mut node = &mut tree;
        for part in s.package.split('.').filter(|p| !p.is_empty()) {
            node = node.children.entry(part.to_owned()).or_default();
        }
        node.structs.push(s);
    }
    let mut out = String::from("// Generated by stride-lcm-gen from .lcm files; do not edit.\n\n");
    emit_tree(&mut out, set, &tree, "", opts);
    if opts.registry {
        out.push_str("/// Every generated type: its full LCM name and its fingerprint.\npub const TYPES: &[(&str, u64)] = &[\n");
        for s in set.structs() {
            let full = s.full_name();
            let _ = writeln!(out, "    ({full:?}, {:#018x}),", set.fingerprint(&full));
        }
        out.push_str("];\n\n");
    }
    if let Some(gate) = opts.serde.attr("json") {
        out.push_str(&gate);
        out.push_str(concat!(
            "/// A float as JSON: a number when finite, else the string `\"NaN\"`, `\"inf\"` or `\"-inf\"`\n",
            "/// (JSON has no number for them).\n",
            "pub fn json_float(v: f64) -> serde_json::Value {\n",
            "    if v.is_nan() {\n        serde_json::Value::from(\"NaN\")\n",
            "    } else if v == f64::INFINITY {\n        serde_json::Value::from(\"inf\")\n",
            "    } else if v == f64::NEG_INFINITY {\n        serde_json::Value::from(\"-inf\")\n",
            "    } else {\n        serde_json::Value::from(v)\n    }\n}\n\n",
        ));
    }
    if let (true, Some(gate)) = (opts.registry, opts.serde.attr("json")) {
        out.push_str(&gate);
        out.push_str(
            "/// Decodes any generated type, recognised by its fingerprint, to JSON (its `to_json`): the\n/// type's name and the value, or `None` when no type has that fingerprint.\npub fn decode_json(data: &[u8]) -> Option<(&'static str, Result<serde_json::Value, String>)> {\n    let fp = u64::from_be_bytes(data.get(..8)?.try_into().ok()?);\n    match fp {\n",
        );
        for s in set.structs() {
            let full = s.full_name();
            let _ = writeln!(
                out,
                "        {:#018x} => Some(({full:?}, <{} as lcm::Message>::decode(data).map(|m| m.to_json()).map_err(|e| e.to_string()))),",
                set.fingerprint(&full),
                type_path("", &full)
            );
        }
        out.push_str("        _ => None,\n    }\n}\n\n");
        out.push_str(&gate);
        out.push_str(
            "/// The JSON Schema of a generated type's JSON form (its `JSON_SCHEMA`), by full LCM name.\npub fn json_schema(type_name: &str) -> Option<&'static str> {\n    match type_name {\n",
        );
        for s in set.structs() {
            let full = s.full_name();
            let _ = writeln!(
                out,
                "        {full:?} => Some({}::JSON_SCHEMA),",
                type_path("", &full)
            );
        }
        out.push_str("        _ => None,\n    }\n}\n");
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names() {
        assert_eq!(type_name("node_status_t"), "NodeStatusT");
        assert_eq!(type_name("pose"), "Pose");
        assert_eq!(type_name("_x__y_"), "XY");
        assert_eq!(ident("type"), "r#type");
        assert_eq!(ident("self"), "self_");
        assert_eq!(ident("x"), "x");
        assert_eq!(type_path("a.b", "c.d_t"), "super::super::c::DT");
        assert_eq!(type_path("", "c.d_t"), "c::DT");
        assert_eq!(type_path("a", "top_t"), "super::TopT");
    }

    #[test]
    fn generates_for_every_shape() {
        let set = TypeSet::from_sources([(
            "s.lcm",
            "package p; struct s_t { const double PI = 3.14; const int32_t K = 010;
               int32_t n; int16_t m; double a[3][2]; float b[n][3]; int8_t c[2][n];
               byte raw[n]; boolean flags[n]; string names[2]; q_t q; q_t qs[n]; q_t qq[3]; double big[40]; }
             struct q_t { int64_t sequence; }",
        )])
        .unwrap();
        let code = generate(&set, &Options::default());
        assert!(code.contains("pub const K: i32 = 8;"));
        assert!(code.contains("pub const PI: f64 = 3.14;"));
        assert!(code.contains("pub b: Vec<[f32; 3]>,"));
        assert!(code.contains("pub c: [Vec<i8>; 2],"));
        assert!(code.contains("serde_big_array::BigArray"));
        assert!(code.contains("Some(self.sequence)"));
    }
}
