//! Signal types and values.

use std::fmt;

use cetratus_vocab::UnknownName;

/// The type of a signal (input, output or variable).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Type {
    /// A level: true or false.
    Bool,
    /// A 64-bit signed integer.
    Int,
    /// A 64-bit float.
    Real,
}

impl Type {
    /// The name used in program files.
    pub fn name(self) -> &'static str {
        match self {
            Type::Bool => "bool",
            Type::Int => "int",
            Type::Real => "real",
        }
    }

    /// The value a signal of this type has when nothing set it: false, 0 or 0.0.
    pub fn zero(self) -> Value {
        match self {
            Type::Bool => Value::Bool(false),
            Type::Int => Value::Int(0),
            Type::Real => Value::Real(0.0),
        }
    }
}

impl fmt::Display for Type {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Type {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, UnknownName> {
        match s {
            "bool" => Ok(Type::Bool),
            "int" => Ok(Type::Int),
            "real" => Ok(Type::Real),
            other => Err(UnknownName {
                what: "type",
                value: other.chars().take(64).collect(),
                expected: "bool, int or real",
            }),
        }
    }
}

/// The value of a signal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    /// A bool.
    Bool(bool),
    /// An int.
    Int(i64),
    /// A real.
    Real(f64),
}

impl Value {
    /// The value's type.
    pub fn ty(self) -> Type {
        match self {
            Value::Bool(_) => Type::Bool,
            Value::Int(_) => Type::Int,
            Value::Real(_) => Type::Real,
        }
    }

    /// The bool inside, if it is one.
    pub fn as_bool(self) -> Option<bool> {
        match self {
            Value::Bool(b) => Some(b),
            _ => None,
        }
    }
}

impl Default for Value {
    fn default() -> Self {
        Value::Bool(false)
    }
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Bool(b) => write!(f, "{b}"),
            Value::Int(i) => write!(f, "{i}"),
            Value::Real(r) => write!(f, "{r:?}"),
        }
    }
}

/// A declared input, output or variable.
#[derive(Clone, Debug, PartialEq)]
pub struct Signal {
    /// Unique among all signals of the program.
    pub name: String,
    /// Its type.
    pub ty: Type,
    /// The I/O address (`%IX0.0`), for inputs and outputs that declare one.
    pub address: Option<String>,
    /// Free text for people.
    pub description: String,
    /// Inputs and outputs: the value an output is sent when the PLC faults, and the value an
    /// input takes when its field device is silent (docs/io.md), if declared.
    pub safe: Option<Value>,
    /// The value at start: the variable's `initial`, else the type's zero.
    pub initial: Value,
    /// Variables only: kept across a warm restart.
    pub retain: bool,
}
