//! JSON Schemas of the LCM types, for the JSON form the generated `to_json` writes.
//!
//! A struct is an object with every member required and nothing else; integers are `integer`
//! with their type's bounds, `float` and `double` are `number`, `byte` is an integer 0-255, and
//! arrays are arrays (fixed dimensions with their length). Nested structs are written in place;
//! a struct that contains itself (through a variable-length array) refers back to its
//! enclosing schema with `$ref`.
//!
//! A float that is NaN or infinite is written as the string `"NaN"`, `"inf"` or `"-inf"`, which
//! the schema does not admit: a float member's schema is `{"type": "number"}` because viewers
//! such as Foxglove read each member's `type` as a single name. The root's `$comment` says so.

use std::fmt::Write;

use crate::ast::{Dim, Primitive, TypeRef};
use crate::TypeSet;

/// The `$comment` of every root schema: how non-finite floats appear.
pub const NON_FINITE_NOTE: &str = "A float or double member that is NaN, +infinity or -infinity holds the string \"NaN\", \"inf\" or \"-inf\" instead of a number.";

/// A JSON value, enough to write schemas: objects keep their keys in order.
#[derive(Debug, Clone, PartialEq)]
pub enum Json {
    /// A string.
    Str(String),
    /// A number, as written.
    Num(String),
    /// `true` or `false`.
    Bool(bool),
    /// An array.
    Arr(Vec<Json>),
    /// An object, keys in order.
    Obj(Vec<(String, Json)>),
}

impl Json {
    fn str(s: &str) -> Json {
        Json::Str(s.to_owned())
    }

    fn obj(pairs: Vec<(&str, Json)>) -> Json {
        Json::Obj(pairs.into_iter().map(|(k, v)| (k.to_owned(), v)).collect())
    }

    /// Compact JSON text.
    pub fn to_text(&self) -> String {
        let mut out = String::new();
        self.write(&mut out);
        out
    }

    fn write(&self, out: &mut String) {
        match self {
            Json::Str(s) => write_str(out, s),
            Json::Num(n) => out.push_str(n),
            Json::Bool(b) => out.push_str(if *b { "true" } else { "false" }),
            Json::Arr(items) => {
                out.push('[');
                for (i, x) in items.iter().enumerate() {
                    if i > 0 {
                        out.push(',');
                    }
                    x.write(out);
                }
                out.push(']');
            }
            Json::Obj(pairs) => {
                out.push('{');
                for (i, (k, v)) in pairs.iter().enumerate() {
                    if i > 0 {
                        out.push(',');
                    }
                    write_str(out, k);
                    out.push(':');
                    v.write(out);
                }
                out.push('}');
            }
        }
    }
}

fn write_str(out: &mut String, s: &str) {
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if (c as u32) < 0x20 => {
                let _ = write!(out, "\\u{:04x}", c as u32);
            }
            c => out.push(c),
        }
    }
    out.push('"');
}

/// A JSON Pointer token (`~` and `/` escaped).
fn pointer_token(name: &str) -> String {
    name.replace('~', "~0").replace('/', "~1")
}

fn primitive(p: Primitive) -> Json {
    let int = |min: &str, max: &str| {
        Json::obj(vec![
            ("type", Json::str("integer")),
            ("minimum", Json::Num(min.into())),
            ("maximum", Json::Num(max.into())),
        ])
    };
    match p {
        Primitive::Int8 => int("-128", "127"),
        Primitive::Int16 => int("-32768", "32767"),
        Primitive::Int32 => int("-2147483648", "2147483647"),
        Primitive::Int64 => int("-9223372036854775808", "9223372036854775807"),
        Primitive::Byte => int("0", "255"),
        Primitive::Float | Primitive::Double => Json::obj(vec![("type", Json::str("number"))]),
        Primitive::String => Json::obj(vec![("type", Json::str("string"))]),
        Primitive::Boolean => Json::obj(vec![("type", Json::str("boolean"))]),
    }
}

/// The schema of a struct placed at `pointer` in the root schema; `stack` holds the structs
/// being written around it, with their pointers.
fn struct_schema(
    set: &TypeSet,
    full: &str,
    pointer: &str,
    stack: &mut Vec<(String, String)>,
) -> Json {
    if let Some((_, at)) = stack.iter().find(|(name, _)| name == full) {
        return Json::obj(vec![("$ref", Json::Str(format!("#{at}")))]);
    }
    let s = set.get(full).expect("a checked type set");
    stack.push((full.to_owned(), pointer.to_owned()));
    let mut properties = Vec::new();
    for m in &s.members {
        let at = format!("{pointer}/properties/{}", pointer_token(&m.name));
        let mut schema = member_schema(set, &m.ty, &m.dims, &at, stack);
        if let (Some(doc), Json::Obj(pairs)) = (&m.doc, &mut schema) {
            pairs.retain(|(k, _)| k != "description");
            pairs.push(("description".into(), Json::str(doc)));
        }
        properties.push((m.name.clone(), schema));
    }
    stack.pop();
    let mut pairs = vec![("title", Json::str(full))];
    if let Some(doc) = &s.doc {
        pairs.push(("description", Json::str(doc)));
    }
    pairs.extend([
        ("type", Json::str("object")),
        ("properties", Json::Obj(properties)),
        (
            "required",
            Json::Arr(s.members.iter().map(|m| Json::str(&m.name)).collect()),
        ),
        ("additionalProperties", Json::Bool(false)),
    ]);
    Json::obj(pairs)
}

fn member_schema(
    set: &TypeSet,
    ty: &TypeRef,
    dims: &[Dim],
    pointer: &str,
    stack: &mut Vec<(String, String)>,
) -> Json {
    let Some(dim) = dims.first() else {
        return match ty {
            TypeRef::Primitive(p) => primitive(*p),
            TypeRef::Struct(t) => struct_schema(set, t, pointer, stack),
        };
    };
    let items = member_schema(set, ty, &dims[1..], &format!("{pointer}/items"), stack);
    let mut pairs = vec![("type", Json::str("array")), ("items", items)];
    if let Dim::Const { value, .. } = dim {
        pairs.push(("minItems", Json::Num(value.to_string())));
        pairs.push(("maxItems", Json::Num(value.to_string())));
    }
    Json::obj(pairs)
}

/// The JSON Schema (draft 2020-12) of a struct's JSON form, by its full name.
pub fn json_schema(set: &TypeSet, full: &str) -> Json {
    let Json::Obj(mut pairs) = struct_schema(set, full, "", &mut Vec::new()) else {
        unreachable!("a struct's schema is an object")
    };
    pairs.insert(
        0,
        (
            "$schema".into(),
            Json::str("https://json-schema.org/draft/2020-12/schema"),
        ),
    );
    pairs.insert(1, ("$comment".into(), Json::str(NON_FINITE_NOTE)));
    Json::Obj(pairs)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn set(src: &str) -> TypeSet {
        TypeSet::from_sources([("x.lcm", src)]).unwrap()
    }

    #[test]
    fn members_in_declaration_order_with_their_types() {
        let s = set("package p;
            /** A thing. */
            struct a_t { int64_t z; /** Metres. */ double a[2]; int32_t n; b_t bs[n];
                         string s; boolean f; byte raw[n]; float m[n][3]; }
            struct b_t { int8_t k; }");
        let text = json_schema(&s, "p.a_t").to_text();
        assert!(text.starts_with(
            r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","$comment":"#
        ));
        let z = text.find(r#""z":"#).unwrap();
        let a = text.find(r#""a":"#).unwrap();
        let n = text.find(r#""n":"#).unwrap();
        assert!(z < a && a < n, "{text}");
        for part in [
            r#""title":"p.a_t","description":"A thing.","type":"object""#,
            r#""z":{"type":"integer","minimum":-9223372036854775808,"maximum":9223372036854775807}"#,
            r#""a":{"type":"array","items":{"type":"number"},"minItems":2,"maxItems":2,"description":"Metres."}"#,
            r#""bs":{"type":"array","items":{"title":"p.b_t","type":"object","properties":{"k":{"type":"integer","minimum":-128,"maximum":127}},"required":["k"],"additionalProperties":false}}"#,
            r#""s":{"type":"string"}"#,
            r#""f":{"type":"boolean"}"#,
            r#""raw":{"type":"array","items":{"type":"integer","minimum":0,"maximum":255}}"#,
            r#""m":{"type":"array","items":{"type":"array","items":{"type":"number"},"minItems":3,"maxItems":3}}"#,
            r#""required":["z","a","n","bs","s","f","raw","m"],"additionalProperties":false"#,
        ] {
            assert!(text.contains(part), "{part} not in {text}");
        }
    }

    #[test]
    fn a_struct_that_contains_itself_refers_back() {
        let s = set("package p; struct t_t { int32_t n; u_t kids[n]; }
                     struct u_t { int32_t n; t_t back[n]; }
                     struct r_t { t_t t; }");
        let text = json_schema(&s, "p.t_t").to_text();
        assert!(
            text.contains(r##""back":{"type":"array","items":{"$ref":"#"}}"##),
            "{text}"
        );
        let text = json_schema(&s, "p.r_t").to_text();
        assert!(
            text.contains(r##""back":{"type":"array","items":{"$ref":"#/properties/t"}}"##),
            "{text}"
        );
    }

    #[test]
    fn strings_are_escaped() {
        let mut out = String::new();
        write_str(&mut out, "a\"b\\c\nd\u{1}é");
        assert_eq!(out, r#""a\"b\\c\nd\u0001é""#);
        assert_eq!(pointer_token("a/b~c"), "a~1b~0c");
    }
}
