//! The data types of a compiled program, and how a value of each lies in the state.
//!
//! A program's state is two flat buffers: *slots* (`u64`), one per elementary value, and *text*,
//! the bytes of its strings. A structure, array or function block instance is a run of slots and
//! a run of text, its members at fixed offsets, so that copying one is copying two ranges.
//!
//! How an elementary value lies in its slot:
//!
//! | type | slot |
//! |---|---|
//! | BOOL | 0 or 1 |
//! | SINT, INT, DINT, LINT | the value sign-extended to 64 bits |
//! | USINT … ULINT, BYTE … LWORD | the value zero-extended |
//! | REAL | the `f32` bit pattern, zero-extended |
//! | LREAL | the `f64` bit pattern |
//! | TIME | nanoseconds, as an `i64` |
//! | an enumeration | the value's integer, sign-extended |
//!
//! A STRING of capacity `n` is `n + 2` bytes of text: its length (little-endian `u16`), then
//! its characters, the bytes past the length unspecified.

use std::fmt;

/// The elementary types (IEC 61131-3 Table 10), less the date and wide-string types.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Elem {
    /// BOOL.
    Bool,
    /// SINT: 8-bit signed.
    Sint,
    /// INT: 16-bit signed.
    Int,
    /// DINT: 32-bit signed.
    Dint,
    /// LINT: 64-bit signed.
    Lint,
    /// USINT: 8-bit unsigned.
    Usint,
    /// UINT: 16-bit unsigned.
    Uint,
    /// UDINT: 32-bit unsigned.
    Udint,
    /// ULINT: 64-bit unsigned.
    Ulint,
    /// BYTE: 8 bits.
    Byte,
    /// WORD: 16 bits.
    Word,
    /// DWORD: 32 bits.
    Dword,
    /// LWORD: 64 bits.
    Lword,
    /// REAL: IEEE 754 single.
    Real,
    /// LREAL: IEEE 754 double.
    Lreal,
    /// TIME: a duration, in nanoseconds.
    Time,
}

/// Every elementary type, in declaration order.
pub const ELEMS: [Elem; 16] = [
    Elem::Bool,
    Elem::Sint,
    Elem::Int,
    Elem::Dint,
    Elem::Lint,
    Elem::Usint,
    Elem::Uint,
    Elem::Udint,
    Elem::Ulint,
    Elem::Byte,
    Elem::Word,
    Elem::Dword,
    Elem::Lword,
    Elem::Real,
    Elem::Lreal,
    Elem::Time,
];

impl Elem {
    /// The IEC name.
    pub fn name(self) -> &'static str {
        match self {
            Elem::Bool => "BOOL",
            Elem::Sint => "SINT",
            Elem::Int => "INT",
            Elem::Dint => "DINT",
            Elem::Lint => "LINT",
            Elem::Usint => "USINT",
            Elem::Uint => "UINT",
            Elem::Udint => "UDINT",
            Elem::Ulint => "ULINT",
            Elem::Byte => "BYTE",
            Elem::Word => "WORD",
            Elem::Dword => "DWORD",
            Elem::Lword => "LWORD",
            Elem::Real => "REAL",
            Elem::Lreal => "LREAL",
            Elem::Time => "TIME",
        }
    }

    /// The type named `upper` (an upper-case name), if it is elementary. `LTIME` is TIME: both
    /// count nanoseconds in 64 bits here.
    pub fn from_name(upper: &str) -> Option<Elem> {
        match upper {
            "LTIME" => Some(Elem::Time),
            _ => ELEMS.iter().copied().find(|e| e.name() == upper),
        }
    }

    /// Width in bits (BOOL: 1).
    pub fn bits(self) -> u32 {
        match self {
            Elem::Bool => 1,
            Elem::Sint | Elem::Usint | Elem::Byte => 8,
            Elem::Int | Elem::Uint | Elem::Word => 16,
            Elem::Dint | Elem::Udint | Elem::Dword | Elem::Real => 32,
            Elem::Lint | Elem::Ulint | Elem::Lword | Elem::Lreal | Elem::Time => 64,
        }
    }

    /// ANY_INT, signed.
    pub fn is_signed(self) -> bool {
        matches!(self, Elem::Sint | Elem::Int | Elem::Dint | Elem::Lint)
    }

    /// ANY_INT: signed and unsigned integers.
    pub fn is_int(self) -> bool {
        self.is_signed() || matches!(self, Elem::Usint | Elem::Uint | Elem::Udint | Elem::Ulint)
    }

    /// ANY_BIT without BOOL: the bit strings.
    pub fn is_bits(self) -> bool {
        matches!(self, Elem::Byte | Elem::Word | Elem::Dword | Elem::Lword)
    }

    /// ANY_REAL.
    pub fn is_real(self) -> bool {
        matches!(self, Elem::Real | Elem::Lreal)
    }

    /// ANY_NUM: integers and reals.
    pub fn is_num(self) -> bool {
        self.is_int() || self.is_real()
    }

    /// The smallest and largest value of an integer or bit-string type, as i128.
    pub fn int_range(self) -> (i128, i128) {
        let bits = self.bits();
        if self.is_signed() {
            (-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1)
        } else {
            (0, (1i128 << bits) - 1)
        }
    }
}

impl fmt::Display for Elem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Brings 64 raw bits to the canonical slot form of an integer, bit-string or BOOL type: the
/// low `bits` kept, sign- or zero-extended. This is the two's-complement wrap of IEC arithmetic
/// (as MATIEC's C and CODESYS make it).
#[inline]
pub fn wrap(e: Elem, v: u64) -> u64 {
    match e {
        Elem::Sint => v as i8 as i64 as u64,
        Elem::Int => v as i16 as i64 as u64,
        Elem::Dint => v as i32 as i64 as u64,
        Elem::Usint | Elem::Byte => v & 0xff,
        Elem::Uint | Elem::Word => v & 0xffff,
        Elem::Udint | Elem::Dword => v & 0xffff_ffff,
        Elem::Bool => (v != 0) as u64,
        _ => v,
    }
}

/// The capacity of a STRING declared without one (CODESYS's and TwinCAT's; MATIEC's is 126).
pub const DEFAULT_STRING: u16 = 80;
/// The largest capacity a STRING may declare.
pub const MAX_STRING: u16 = 1024;

/// Index of a declared array type in [`Types::arrays`].
pub type ArrayId = u32;
/// Index of a structure type in [`Types::structs`].
pub type StructId = u32;
/// Index of an enumeration in [`Types::enums`].
pub type EnumId = u32;
/// Index of a function block type in the compiled unit's blocks.
pub type FbId = u32;

/// The type of a value, checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Ty {
    /// An elementary type.
    Elem(Elem),
    /// A STRING of this capacity.
    String(u16),
    /// An array.
    Array(ArrayId),
    /// A structure.
    Struct(StructId),
    /// An enumeration.
    Enum(EnumId),
    /// A function block instance.
    Fb(FbId),
}

impl Ty {
    /// The elementary type, if it is one.
    pub fn elem(self) -> Option<Elem> {
        match self {
            Ty::Elem(e) => Some(e),
            _ => None,
        }
    }

    /// True when a value of this type sits in one slot (elementary or enumeration).
    pub fn is_scalar(self) -> bool {
        matches!(self, Ty::Elem(_) | Ty::Enum(_))
    }
}

/// How much state a value takes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Size {
    /// Slots.
    pub slots: u32,
    /// Bytes of text.
    pub text: u32,
}

impl Size {
    /// The size of `n` values of this size, if it fits.
    pub fn times(self, n: u64) -> Option<Size> {
        Some(Size {
            slots: u32::try_from(u64::from(self.slots).checked_mul(n)?).ok()?,
            text: u32::try_from(u64::from(self.text).checked_mul(n)?).ok()?,
        })
    }

    /// The two sizes laid end to end, if it fits.
    pub fn plus(self, other: Size) -> Option<Size> {
        Some(Size {
            slots: self.slots.checked_add(other.slots)?,
            text: self.text.checked_add(other.text)?,
        })
    }
}

/// An array type: its dimensions, element type, and sizes.
#[derive(Clone, Debug, PartialEq)]
pub struct ArrayTy {
    /// Lower and upper bound of each dimension.
    pub dims: Vec<(i64, i64)>,
    /// The element type.
    pub elem: Ty,
    /// The size of one element.
    pub elem_size: Size,
}

impl ArrayTy {
    /// Number of elements in all.
    pub fn count(&self) -> u64 {
        self.dims
            .iter()
            .map(|(lo, hi)| (hi - lo + 1) as u64)
            .product()
    }
}

/// A member of a structure or an FB instance, at its offset.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    /// The name, upper case.
    pub key: String,
    /// The name as declared.
    pub name: String,
    /// Its type.
    pub ty: Ty,
    /// Its offset in the enclosing value.
    pub at: Size,
}

/// A structure type.
#[derive(Clone, Debug, PartialEq)]
pub struct StructTy {
    /// Its name as declared.
    pub name: String,
    /// Its members, in order.
    pub fields: Vec<Field>,
    /// Its size.
    pub size: Size,
}

/// An enumeration type.
#[derive(Clone, Debug, PartialEq)]
pub struct EnumTy {
    /// Its name as declared.
    pub name: String,
    /// Each value's name (upper case) and integer.
    pub values: Vec<(String, i64)>,
}

/// The declared types of a program.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Types {
    /// Arrays, by [`ArrayId`].
    pub arrays: Vec<ArrayTy>,
    /// Structures, by [`StructId`].
    pub structs: Vec<StructTy>,
    /// Enumerations, by [`EnumId`].
    pub enums: Vec<EnumTy>,
}

impl Types {
    /// The name of `ty`, for messages; `fb_name` names FB types.
    pub fn describe(&self, ty: Ty, fb_name: &dyn Fn(FbId) -> String) -> String {
        match ty {
            Ty::Elem(e) => e.name().to_string(),
            Ty::String(n) => format!("STRING[{n}]"),
            Ty::Array(id) => {
                let a = &self.arrays[id as usize];
                let dims: Vec<String> = a.dims.iter().map(|(l, h)| format!("{l}..{h}")).collect();
                format!(
                    "ARRAY [{}] OF {}",
                    dims.join(", "),
                    self.describe(a.elem, fb_name)
                )
            }
            Ty::Struct(id) => self.structs[id as usize].name.clone(),
            Ty::Enum(id) => self.enums[id as usize].name.clone(),
            Ty::Fb(id) => fb_name(id),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_keeps_the_low_bits_with_the_sign_of_the_type() {
        assert_eq!(wrap(Elem::Int, 32768) as i64, -32768);
        assert_eq!(wrap(Elem::Sint, 255) as i64, -1);
        assert_eq!(wrap(Elem::Usint, (-1i64) as u64), 255);
        assert_eq!(wrap(Elem::Udint, 1 << 32), 0);
        assert_eq!(wrap(Elem::Bool, 2), 1);
    }

    #[test]
    fn names_read_back_to_their_type() {
        for e in ELEMS {
            assert_eq!(Elem::from_name(e.name()), Some(e));
        }
        assert_eq!(Elem::from_name("LTIME"), Some(Elem::Time));
        assert_eq!(Elem::Int.int_range(), (-32768, 32767));
        assert_eq!(Elem::Lword.int_range(), (0, u64::MAX as i128));
    }
}
