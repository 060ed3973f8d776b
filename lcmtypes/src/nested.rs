//! The JSON form for MCAP files and viewers such as Foxglove, whose JSON Schema reader takes no
//! array whose items are arrays: every array of arrays (a member declared with two or more
//! dimensions, such as `double positions[num_rows][num_joints]`) becomes an array of objects,
//! each holding one inner array under the key `"values"` (for three dimensions, nested again
//! the same way). `positions: [[1, 2], [3, 4]]` becomes
//! `positions: [{"values": [1, 2]}, {"values": [3, 4]}]`, read in Foxglove as
//! `.positions[1].values[0]`. Everything else is as `to_json` and `JSON_SCHEMA` have it.

use serde_json::{Map, Value};

/// The key of an inner array in its wrapping object.
pub const VALUES_KEY: &str = "values";

fn wrap(value: Value) -> Value {
    let mut m = Map::with_capacity(1);
    m.insert(VALUES_KEY.to_owned(), value);
    Value::Object(m)
}

/// `to_json`'s value with every array of arrays turned into an array of `{"values": [..]}`
/// objects (at every depth, inside nested structs too).
pub fn wrap_nested_arrays(value: Value) -> Value {
    match value {
        Value::Array(items) => Value::Array(
            items
                .into_iter()
                .map(|x| match x {
                    inner @ Value::Array(_) => wrap(wrap_nested_arrays(inner)),
                    other => wrap_nested_arrays(other),
                })
                .collect(),
        ),
        Value::Object(m) => Value::Object(
            m.into_iter()
                .map(|(k, v)| (k, wrap_nested_arrays(v)))
                .collect(),
        ),
        other => other,
    }
}

/// A JSON Pointer token (`~` and `/` escaped).
fn token(name: &str) -> String {
    name.replace('~', "~0").replace('/', "~1")
}

fn is_array_schema(v: &Value) -> bool {
    v.get("type").and_then(Value::as_str) == Some("array")
}

/// `schema` (at `old` in the original root, `new` in the rewritten one) with every array of
/// arrays' items wrapped in an object with the one member `values`; `$ref`s to enclosing
/// schemas follow them to their new place (`seen`: the enclosing objects' old and new pointers).
fn rewrite(schema: &Value, old: &str, new: &str, seen: &mut Vec<(String, String)>) -> Value {
    match schema {
        Value::Object(m) => {
            seen.push((old.to_owned(), new.to_owned()));
            let nested = is_array_schema(schema) && m.get("items").is_some_and(is_array_schema);
            let mut out = Map::with_capacity(m.len());
            for (k, v) in m {
                let (o, n) = (format!("{old}/{}", token(k)), format!("{new}/{}", token(k)));
                let v = match (k.as_str(), v) {
                    ("$ref", Value::String(r)) => Value::String(
                        r.strip_prefix('#')
                            .and_then(|p| seen.iter().rev().find(|(o, _)| o == p))
                            .map_or_else(|| r.clone(), |(_, n)| format!("#{n}")),
                    ),
                    ("items", items) if nested => {
                        let inner =
                            rewrite(items, &o, &format!("{n}/properties/{VALUES_KEY}"), seen);
                        let mut properties = Map::with_capacity(1);
                        properties.insert(VALUES_KEY.to_owned(), inner);
                        let mut w = Map::with_capacity(4);
                        w.insert("type".into(), "object".into());
                        w.insert("properties".into(), Value::Object(properties));
                        w.insert("required".into(), Value::Array(vec![VALUES_KEY.into()]));
                        w.insert("additionalProperties".into(), false.into());
                        Value::Object(w)
                    }
                    (_, v) => rewrite(v, &o, &n, seen),
                };
                out.insert(k.clone(), v);
            }
            seen.pop();
            Value::Object(out)
        }
        Value::Array(items) => Value::Array(
            items
                .iter()
                .enumerate()
                .map(|(i, x)| rewrite(x, &format!("{old}/{i}"), &format!("{new}/{i}"), seen))
                .collect(),
        ),
        other => other.clone(),
    }
}

/// A JSON Schema of `to_json`'s form rewritten for [`wrap_nested_arrays`]'s: every array
/// whose items are arrays gets items `{"type": "object", "properties": {"values": <the inner
/// array>}, "required": ["values"], "additionalProperties": false}`.
pub fn wrap_nested_array_schema(schema: &Value) -> Value {
    rewrite(schema, "", "", &mut Vec::new())
}

/// The JSON Schema of a generated type's [`wrap_nested_arrays`] form, by full LCM name.
pub fn nested_json_schema(type_name: &str) -> Option<String> {
    let schema: Value = serde_json::from_str(crate::json_schema(type_name)?).ok()?;
    Some(wrap_nested_array_schema(&schema).to_string())
}

/// Decodes any generated type, recognised by its fingerprint, to its [`wrap_nested_arrays`]
/// form: the type's name and the value, or `None` when no type has that fingerprint.
pub fn decode_nested_json(data: &[u8]) -> Option<(&'static str, Result<Value, String>)> {
    crate::decode_json(data).map(|(ty, v)| (ty, v.map(wrap_nested_arrays)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn arrays_of_arrays_are_wrapped_at_every_depth() {
        let v = json!({"a": [1, 2], "m": [[1, 2], [3]], "c": [[[1], [2]], []], "s": [{"p": [[0.5]]}], "e": []});
        assert_eq!(
            wrap_nested_arrays(v),
            json!({"a": [1, 2], "m": [{"values": [1, 2]}, {"values": [3]}],
                   "c": [{"values": [{"values": [1]}, {"values": [2]}]}, {"values": []}],
                   "s": [{"p": [{"values": [0.5]}]}], "e": []})
        );
    }

    #[test]
    fn schemas_are_wrapped_and_refs_follow() {
        let s = json!({"type": "object", "properties": {
            "m": {"type": "array", "items": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}},
            "t": {"type": "array", "items": {"type": "array", "items": {"type": "object", "properties": {
                "back": {"type": "array", "items": {"$ref": "#/properties/t/items/items"}},
                "root": {"$ref": "#"}}}}}}});
        let w = wrap_nested_array_schema(&s);
        assert_eq!(
            w["properties"]["m"]["items"],
            json!({"type": "object", "properties": {"values": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}},
                   "required": ["values"], "additionalProperties": false})
        );
        let inner = &w["properties"]["t"]["items"]["properties"]["values"]["items"];
        assert_eq!(
            inner["properties"]["back"]["items"]["$ref"],
            "#/properties/t/items/properties/values/items"
        );
        assert_eq!(inner["properties"]["root"]["$ref"], "#");
    }
}
