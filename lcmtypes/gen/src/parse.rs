//! Tokenizer and parser of the LCM type language.

use crate::ast::{Const, ConstValue, Dim, Member, Primitive, Struct, TypeRef};

/// A parse or validation error, with its place.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Error {
    /// File name.
    pub file: String,
    /// 1-based line (0 when not tied to a line).
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

impl std::fmt::Display for Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.line > 0 {
            write!(f, "{}:{}: {}", self.file, self.line, self.message)
        } else {
            write!(f, "{}: {}", self.file, self.message)
        }
    }
}

impl std::error::Error for Error {}

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Ident(String),
    Number(String),
    Punct(char),
}

#[derive(Debug, Clone)]
struct Token {
    tok: Tok,
    line: usize,
    /// Comment text written just before this token.
    doc: Option<String>,
}

fn clean_comment(raw: &str, block: bool) -> String {
    if !block {
        return raw.trim().to_owned();
    }
    let lines: Vec<String> = raw
        .lines()
        .map(|l| {
            let t = l.trim();
            let t = t.strip_prefix('*').unwrap_or(t);
            t.trim().to_owned()
        })
        .collect();
    let text = lines.join("\n");
    text.trim_matches(|c: char| c == '*' || c.is_whitespace())
        .to_owned()
}

fn tokenize(file: &str, src: &str) -> Result<Vec<Token>, Error> {
    let b = src.as_bytes();
    let mut i = 0;
    let mut line = 1;
    let mut out = Vec::new();
    let mut doc: Vec<String> = Vec::new();
    let err = |line, message: String| Error {
        file: file.to_owned(),
        line,
        message,
    };
    while i < b.len() {
        let c = b[i];
        if c == b'\n' {
            line += 1;
            i += 1;
        } else if c.is_ascii_whitespace() {
            i += 1;
        } else if b[i..].starts_with(b"//") {
            let end = src[i..].find('\n').map_or(b.len(), |n| i + n);
            doc.push(clean_comment(&src[i + 2..end], false));
            i = end;
        } else if b[i..].starts_with(b"/*") {
            let end = src[i + 2..]
                .find("*/")
                .map(|n| i + 2 + n)
                .ok_or_else(|| err(line, "unterminated /* comment".into()))?;
            let body = &src[i + 2..end];
            line += body.matches('\n').count();
            doc.push(clean_comment(body, true));
            i = end + 2;
        } else if c.is_ascii_alphabetic() || c == b'_' {
            let start = i;
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                i += 1;
            }
            out.push(Token {
                tok: Tok::Ident(src[start..i].to_owned()),
                line,
                doc: take_doc(&mut doc),
            });
        } else if c.is_ascii_digit()
            || ((c == b'-' || c == b'+' || c == b'.')
                && i + 1 < b.len()
                && (b[i + 1].is_ascii_digit() || b[i + 1] == b'.'))
        {
            let start = i;
            i += 1;
            while i < b.len()
                && (b[i].is_ascii_alphanumeric()
                    || b[i] == b'.'
                    || ((b[i] == b'-' || b[i] == b'+') && matches!(b[i - 1], b'e' | b'E')))
            {
                i += 1;
            }
            out.push(Token {
                tok: Tok::Number(src[start..i].to_owned()),
                line,
                doc: take_doc(&mut doc),
            });
        } else if b"{}[];,=.".contains(&c) {
            out.push(Token {
                tok: Tok::Punct(c as char),
                line,
                doc: take_doc(&mut doc),
            });
            i += 1;
        } else {
            return Err(err(
                line,
                format!(
                    "unexpected character {:?}",
                    src[i..].chars().next().unwrap()
                ),
            ));
        }
    }
    Ok(out)
}

fn take_doc(doc: &mut Vec<String>) -> Option<String> {
    let d: Vec<String> = doc.drain(..).filter(|s| !s.is_empty()).collect();
    if d.is_empty() {
        None
    } else {
        Some(d.join("\n"))
    }
}

/// Parses an integer literal the way C's `strtoll(text, 0)` does: decimal, `0x` hex, `0` octal.
pub fn parse_int(text: &str) -> Option<i64> {
    let (neg, body) = match text.as_bytes().first()? {
        b'-' => (true, &text[1..]),
        b'+' => (false, &text[1..]),
        _ => (false, text),
    };
    let (radix, digits) =
        if let Some(h) = body.strip_prefix("0x").or_else(|| body.strip_prefix("0X")) {
            (16, h)
        } else if body.len() > 1 && body.starts_with('0') {
            (8, &body[1..])
        } else {
            (10, body)
        };
    if digits.is_empty() {
        return None;
    }
    let mag = i128::from_str_radix(digits, radix).ok()?;
    let v = if neg { -mag } else { mag };
    i64::try_from(v).ok()
}

struct Parser<'a> {
    file: &'a str,
    toks: Vec<Token>,
    pos: usize,
}

impl Parser<'_> {
    fn err(&self, message: impl Into<String>) -> Error {
        let line = self
            .toks
            .get(self.pos)
            .or(self.toks.last())
            .map_or(0, |t| t.line);
        Error {
            file: self.file.to_owned(),
            line,
            message: message.into(),
        }
    }

    fn peek(&self) -> Option<&Tok> {
        self.toks.get(self.pos).map(|t| &t.tok)
    }

    fn next(&mut self) -> Result<Token, Error> {
        let t = self
            .toks
            .get(self.pos)
            .cloned()
            .ok_or_else(|| self.err("unexpected end of file"))?;
        self.pos += 1;
        Ok(t)
    }

    fn punct(&mut self, c: char) -> Result<(), Error> {
        match self.peek() {
            Some(Tok::Punct(p)) if *p == c => {
                self.pos += 1;
                Ok(())
            }
            other => Err(self.err(format!("expected '{c}', found {}", describe(other)))),
        }
    }

    fn is_punct(&self, c: char) -> bool {
        matches!(self.peek(), Some(Tok::Punct(p)) if *p == c)
    }

    fn ident(&mut self) -> Result<String, Error> {
        match self.peek() {
            Some(Tok::Ident(s)) => {
                let s = s.clone();
                self.pos += 1;
                if s.len() >= 128 {
                    return Err(self.err(format!(
                        "identifier {s:?} is 128 bytes or longer (its fingerprint would differ between lcm-gen builds)"
                    )));
                }
                Ok(s)
            }
            other => Err(self.err(format!("expected a name, found {}", describe(other)))),
        }
    }

    fn qualified(&mut self) -> Result<String, Error> {
        let mut name = self.ident()?;
        while self.is_punct('.') {
            self.pos += 1;
            name.push('.');
            name.push_str(&self.ident()?);
        }
        Ok(name)
    }
}

fn describe(t: Option<&Tok>) -> String {
    match t {
        None => "end of file".into(),
        Some(Tok::Ident(s)) => format!("{s:?}"),
        Some(Tok::Number(s)) => format!("number {s}"),
        Some(Tok::Punct(c)) => format!("'{c}'"),
    }
}

/// Parses one `.lcm` file into its structs. `file` names it in errors.
///
/// Names of user types are resolved against this file's package only (lcm-gen carries a
/// package over to later files of the same invocation; this parser does not).
pub fn parse_file(file: &str, src: &str) -> Result<Vec<Struct>, Error> {
    let mut p = Parser {
        file,
        toks: tokenize(file, src)?,
        pos: 0,
    };
    let mut package = String::new();
    let mut out = Vec::new();
    while let Some(tok) = p.peek().cloned() {
        match tok {
            Tok::Ident(kw) if kw == "package" => {
                p.pos += 1;
                package = p.qualified()?;
                p.punct(';')?;
            }
            Tok::Ident(kw) if kw == "struct" => {
                let doc = p.toks[p.pos].doc.clone();
                p.pos += 1;
                let mut s = parse_struct(&mut p, &package)?;
                s.doc = doc;
                out.push(s);
            }
            Tok::Ident(kw) if kw == "enum" => {
                return Err(p.err("enum declarations are not supported (deprecated in LCM)"))
            }
            other => {
                return Err(p.err(format!(
                    "expected 'package' or 'struct', found {}",
                    describe(Some(&other))
                )))
            }
        }
    }
    Ok(out)
}

fn parse_struct(p: &mut Parser<'_>, package: &str) -> Result<Struct, Error> {
    let name = p.ident()?;
    p.punct('{')?;
    let mut s = Struct {
        package: package.to_owned(),
        name,
        members: Vec::new(),
        consts: Vec::new(),
        doc: None,
        file: p.file.to_owned(),
    };
    loop {
        if p.is_punct('}') {
            p.pos += 1;
            break;
        }
        let doc = p.toks.get(p.pos).and_then(|t| t.doc.clone());
        let first = p.qualified()?;
        if first == "const" {
            parse_const(p, &mut s, doc)?;
            continue;
        }
        if first == "struct" || first == "enum" {
            return Err(p.err("nested struct or enum declarations are not supported"));
        }
        let ty = match Primitive::from_name(&first) {
            Some(prim) => TypeRef::Primitive(prim),
            None if first.contains('.') => TypeRef::Struct(first.clone()),
            None if package.is_empty() => TypeRef::Struct(first.clone()),
            None => TypeRef::Struct(format!("{package}.{first}")),
        };
        let mut doc = doc;
        loop {
            let mname = p.ident()?;
            let mut dims = Vec::new();
            while p.is_punct('[') {
                p.pos += 1;
                let t = p.next()?;
                let dim = match t.tok {
                    Tok::Number(text) => {
                        let v = parse_int(&text).filter(|v| *v > 0).ok_or_else(|| {
                            p.err(format!("array size {text} is not a positive integer"))
                        })?;
                        Dim::Const {
                            text,
                            value: v as usize,
                        }
                    }
                    Tok::Ident(var) => resolve_dim(p, &s, &var)?,
                    other => {
                        return Err(p.err(format!(
                            "expected an array size, found {}",
                            describe(Some(&other))
                        )))
                    }
                };
                dims.push(dim);
                p.punct(']')?;
            }
            if s.members.iter().any(|m| m.name == mname) || s.consts.iter().any(|c| c.name == mname)
            {
                return Err(p.err(format!("duplicate name {mname:?} in {}", s.name)));
            }
            s.members.push(Member {
                name: mname,
                ty: ty.clone(),
                dims,
                doc: doc.take(),
            });
            if p.is_punct(',') {
                p.pos += 1;
                continue;
            }
            p.punct(';')?;
            break;
        }
    }
    Ok(s)
}

fn resolve_dim(p: &Parser<'_>, s: &Struct, var: &str) -> Result<Dim, Error> {
    if let Some(m) = s.members.iter().find(|m| m.name == var) {
        return match (&m.ty, m.dims.is_empty()) {
            (TypeRef::Primitive(prim), true) if prim.is_integer() => Ok(Dim::Var(var.to_owned())),
            _ => Err(p.err(format!(
                "array size {var:?} must be an integer member (int8_t..int64_t) declared before"
            ))),
        };
    }
    if let Some(c) = s.consts.iter().find(|c| c.name == var) {
        return match c.value {
            ConstValue::Int(v) if v > 0 && c.ty.is_integer() => Ok(Dim::Const {
                text: c.text.clone(),
                value: v as usize,
            }),
            _ => Err(p.err(format!("constant {var:?} is not a positive integer"))),
        };
    }
    Err(p.err(format!(
        "unknown array size {var:?}: it must be an integer member declared before, or a constant"
    )))
}

fn parse_const(p: &mut Parser<'_>, s: &mut Struct, mut doc: Option<String>) -> Result<(), Error> {
    let tname = p.ident()?;
    let ty = Primitive::from_name(&tname)
        .filter(|t| t.is_integer() || matches!(t, Primitive::Float | Primitive::Double))
        .ok_or_else(|| {
            p.err(format!(
                "constants must be int8_t..int64_t, float or double, not {tname}"
            ))
        })?;
    loop {
        let name = p.ident()?;
        p.punct('=')?;
        let t = p.next()?;
        let text = match t.tok {
            Tok::Number(text) => text,
            other => {
                return Err(p.err(format!(
                    "expected a number for {name}, found {}",
                    describe(Some(&other))
                )))
            }
        };
        let value = if ty.is_integer() {
            let v = parse_int(&text).ok_or_else(|| p.err(format!("{text} is not an integer")))?;
            let (lo, hi) = match ty {
                Primitive::Int8 => (i8::MIN as i64, i8::MAX as i64),
                Primitive::Int16 => (i16::MIN as i64, i16::MAX as i64),
                Primitive::Int32 => (i32::MIN as i64, i32::MAX as i64),
                _ => (i64::MIN, i64::MAX),
            };
            if v < lo || v > hi {
                return Err(p.err(format!("{text} does not fit {tname}")));
            }
            ConstValue::Int(v)
        } else {
            let v: f64 = text
                .parse()
                .map_err(|_| p.err(format!("{text} is not a number")))?;
            if !v.is_finite() {
                return Err(p.err(format!("{text} is not finite")));
            }
            ConstValue::Float(v)
        };
        if s.members.iter().any(|m| m.name == name) || s.consts.iter().any(|c| c.name == name) {
            return Err(p.err(format!("duplicate name {name:?} in {}", s.name)));
        }
        s.consts.push(Const {
            name,
            ty,
            text,
            value,
            doc: doc.take(),
        });
        if p.is_punct(',') {
            p.pos += 1;
            continue;
        }
        p.punct(';')?;
        return Ok(());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integers_like_strtoll() {
        assert_eq!(parse_int("10"), Some(10));
        assert_eq!(parse_int("0x10"), Some(16));
        assert_eq!(parse_int("010"), Some(8));
        assert_eq!(parse_int("-0x0a"), Some(-10));
        assert_eq!(parse_int("0"), Some(0));
        assert_eq!(parse_int("9223372036854775808"), None);
        assert_eq!(parse_int("0x"), None);
        assert_eq!(parse_int("12ab"), None);
    }

    #[test]
    fn parses_every_feature() {
        let src = r#"
            package demo.sub;
            /** A doc. */
            struct sample_t {
                const int8_t MAGIC = 7, OTHER = 0x10;
                const double PI = 3.14;
                int64_t utime; // trailing comment goes to the next member
                int32_t n, m;
                double ranges[n], grid[2][m];
                string names[n];
                point_t p;
                other.pkg.thing_t t[0x3][n];
            }
        "#;
        let s = &parse_file("x.lcm", src).unwrap()[0];
        assert_eq!(s.full_name(), "demo.sub.sample_t");
        assert_eq!(s.doc.as_deref(), Some("A doc."));
        assert_eq!(s.consts.len(), 3);
        assert_eq!(s.consts[1].value, ConstValue::Int(16));
        let names: Vec<_> = s.members.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(
            names,
            ["utime", "n", "m", "ranges", "grid", "names", "p", "t"]
        );
        assert_eq!(s.members[4].dims.len(), 2);
        assert_eq!(s.members[6].ty, TypeRef::Struct("demo.sub.point_t".into()));
        assert_eq!(
            s.members[7].dims[0],
            Dim::Const {
                text: "0x3".into(),
                value: 3
            }
        );
        assert_eq!(
            s.members[1].doc.as_deref(),
            Some("trailing comment goes to the next member")
        );
    }

    #[test]
    fn rejects_what_lcm_gen_rejects_or_should() {
        let bad = [
            (
                "struct a { int32_t x[n]; int32_t n; }",
                "unknown array size",
            ),
            ("struct a { double n; int32_t x[n]; }", "integer member"),
            ("struct a { int32_t x; int32_t x; }", "duplicate"),
            ("struct a { const int8_t X = 300; }", "does not fit"),
            ("struct a { const string S = 1; }", "constants must be"),
            ("struct a { int32_t x[0]; }", "positive"),
            ("struct a { int32_t x }", "expected"),
            ("struct a { struct b { } }", "nested"),
            ("enum e { A }", "enum"),
            ("struct a { int32_t x; ", "end of file"),
            ("/* open", "unterminated"),
        ];
        for (src, want) in bad {
            let e = parse_file("bad.lcm", src).unwrap_err().to_string();
            assert!(e.contains(want), "{src}: {e}");
        }
    }
}
