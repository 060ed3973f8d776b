//! The parsed form of `.lcm` files.

/// A primitive LCM type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Primitive {
    /// `int8_t`
    Int8,
    /// `int16_t`
    Int16,
    /// `int32_t`
    Int32,
    /// `int64_t`
    Int64,
    /// `float`
    Float,
    /// `double`
    Double,
    /// `string`
    String,
    /// `boolean`
    Boolean,
    /// `byte`
    Byte,
}

impl Primitive {
    /// Parses an LCM primitive type name.
    pub fn from_name(name: &str) -> Option<Primitive> {
        Some(match name {
            "int8_t" => Primitive::Int8,
            "int16_t" => Primitive::Int16,
            "int32_t" => Primitive::Int32,
            "int64_t" => Primitive::Int64,
            "float" => Primitive::Float,
            "double" => Primitive::Double,
            "string" => Primitive::String,
            "boolean" => Primitive::Boolean,
            "byte" => Primitive::Byte,
            _ => return None,
        })
    }

    /// The name as written in `.lcm` files (and hashed by lcm-gen).
    pub fn lcm_name(self) -> &'static str {
        match self {
            Primitive::Int8 => "int8_t",
            Primitive::Int16 => "int16_t",
            Primitive::Int32 => "int32_t",
            Primitive::Int64 => "int64_t",
            Primitive::Float => "float",
            Primitive::Double => "double",
            Primitive::String => "string",
            Primitive::Boolean => "boolean",
            Primitive::Byte => "byte",
        }
    }

    /// True for the integer types that may size an array.
    pub fn is_integer(self) -> bool {
        matches!(
            self,
            Primitive::Int8 | Primitive::Int16 | Primitive::Int32 | Primitive::Int64
        )
    }

    /// Encoded size in bytes, `None` for strings.
    pub fn fixed_size(self) -> Option<usize> {
        match self {
            Primitive::Int8 | Primitive::Boolean | Primitive::Byte => Some(1),
            Primitive::Int16 => Some(2),
            Primitive::Int32 | Primitive::Float => Some(4),
            Primitive::Int64 | Primitive::Double => Some(8),
            Primitive::String => None,
        }
    }
}

/// The type of a member: a primitive or a struct named by its full name.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum TypeRef {
    /// A primitive.
    Primitive(Primitive),
    /// A struct, fully qualified (`stride.header_t`, or `foo_t` without package).
    Struct(String),
}

/// One array dimension.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Dim {
    /// A constant size; `text` is as written (`3`, `0x10`), `value` its value.
    Const {
        /// The literal text, hashed by lcm-gen.
        text: String,
        /// Its value.
        value: usize,
    },
    /// A size given by an earlier integer member of the struct.
    Var(String),
}

impl Dim {
    /// Text hashed by lcm-gen.
    pub fn text(&self) -> &str {
        match self {
            Dim::Const { text, .. } => text,
            Dim::Var(name) => name,
        }
    }
}

/// A member of a struct.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Member {
    /// Its name.
    pub name: String,
    /// Its element type.
    pub ty: TypeRef,
    /// Array dimensions, outermost first.
    pub dims: Vec<Dim>,
    /// Comment written before it, if any.
    pub doc: Option<String>,
}

/// A constant.
#[derive(Debug, Clone, PartialEq)]
pub struct Const {
    /// Its name.
    pub name: String,
    /// int8..int64, float or double.
    pub ty: Primitive,
    /// The literal text.
    pub text: String,
    /// The value: integers exactly, floats as parsed.
    pub value: ConstValue,
    /// Comment written before it, if any.
    pub doc: Option<String>,
}

/// A constant's value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ConstValue {
    /// An integer constant.
    Int(i64),
    /// A floating-point constant.
    Float(f64),
}

/// A struct definition.
#[derive(Debug, Clone, PartialEq)]
pub struct Struct {
    /// Package (`a.b`), empty when none.
    pub package: String,
    /// Short name (`header_t`).
    pub name: String,
    /// Members in declaration order.
    pub members: Vec<Member>,
    /// Constants in declaration order.
    pub consts: Vec<Const>,
    /// Comment written before it, if any.
    pub doc: Option<String>,
    /// File it came from, for messages.
    pub file: String,
}

impl Struct {
    /// Fully qualified name (`stride.header_t`).
    pub fn full_name(&self) -> String {
        if self.package.is_empty() {
            self.name.clone()
        } else {
            format!("{}.{}", self.package, self.name)
        }
    }
}
