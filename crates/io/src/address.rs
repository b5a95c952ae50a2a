//! IEC 61131-3 direct addresses (`%IX0.3`, `%QW2`, `%MD1`) and where they live on a Modbus
//! device by default.
//!
//! The default map is OpenPLC's, so that an HMI project written for OpenPLC reads Cetratus the
//! same way:
//!
//! | address | Modbus table | number |
//! |---|---|---|
//! | `%IXa.b` | discrete input | `8a + b` |
//! | `%QXa.b` | coil | `8a + b` |
//! | `%IWn` | input register | `n` |
//! | `%QWn` | holding register | `n` |
//! | `%MWn` | holding register | `1024 + n` |
//! | `%IDn` | input registers | `2n`, `2n + 1` |
//! | `%QDn` | holding registers | `2n`, `2n + 1` |
//! | `%MDn` | holding registers | `2048 + 2n`, `2048 + 2n + 1` |

use std::fmt;

/// The area of an address: what the letter after `%` says.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Area {
    /// `%I`: inputs from the field.
    Input,
    /// `%Q`: outputs to the field.
    Output,
    /// `%M`: memory, which HMIs may write.
    Memory,
}

/// The size of an address: what the second letter says.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Size {
    /// `X`: one bit.
    Bit,
    /// `W`: one 16-bit word.
    Word,
    /// `D`: a 32-bit double word (two registers).
    Double,
}

/// The four Modbus tables.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Table {
    /// Read-only bits (function 2).
    DiscreteInputs,
    /// Read-write bits (functions 1, 5, 15).
    Coils,
    /// Read-only registers (function 4).
    InputRegisters,
    /// Read-write registers (functions 3, 6, 16).
    HoldingRegisters,
}

impl Table {
    /// The name used in messages and docs.
    pub fn name(self) -> &'static str {
        match self {
            Table::DiscreteInputs => "discrete input",
            Table::Coils => "coil",
            Table::InputRegisters => "input register",
            Table::HoldingRegisters => "holding register",
        }
    }

    /// Bits or registers.
    pub fn is_bits(self) -> bool {
        matches!(self, Table::DiscreteInputs | Table::Coils)
    }
}

/// A parsed direct address.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct IecAddress {
    /// `I`, `Q` or `M`.
    pub area: Area,
    /// `X`, `W` or `D`.
    pub size: Size,
    /// The number: for bits, `8 * byte + bit`; otherwise the word or double-word index.
    pub index: u32,
}

/// Bits and words addressable in one Modbus table.
const TABLE_LEN: u32 = 65_536;

impl IecAddress {
    /// The Modbus table of this address, and its first number there, by the default map.
    pub fn default_location(self) -> (Table, u32) {
        match (self.area, self.size) {
            (Area::Input, Size::Bit) => (Table::DiscreteInputs, self.index),
            (Area::Output | Area::Memory, Size::Bit) => (Table::Coils, self.index),
            (Area::Input, Size::Word) => (Table::InputRegisters, self.index),
            (Area::Output, Size::Word) => (Table::HoldingRegisters, self.index),
            (Area::Memory, Size::Word) => (Table::HoldingRegisters, 1024 + self.index),
            (Area::Input, Size::Double) => (Table::InputRegisters, 2 * self.index),
            (Area::Output, Size::Double) => (Table::HoldingRegisters, 2 * self.index),
            (Area::Memory, Size::Double) => (Table::HoldingRegisters, 2048 + 2 * self.index),
        }
    }

    /// Bits (for `X`) or registers (for `W`, `D`) that the address takes.
    pub fn width(self) -> u32 {
        match self.size {
            Size::Bit | Size::Word => 1,
            Size::Double => 2,
        }
    }

    /// The address `n` places after this one, in the same area and size.
    pub fn offset(self, n: u32) -> IecAddress {
        IecAddress {
            index: self.index + n,
            ..self
        }
    }
}

impl fmt::Display for IecAddress {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let area = match self.area {
            Area::Input => 'I',
            Area::Output => 'Q',
            Area::Memory => 'M',
        };
        match self.size {
            Size::Bit => write!(f, "%{area}X{}.{}", self.index / 8, self.index % 8),
            Size::Word => write!(f, "%{area}W{}", self.index),
            Size::Double => write!(f, "%{area}D{}", self.index),
        }
    }
}

/// Text that is not an IEC address: the text and what is wrong with it.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("`{text}` is not an IEC address: {why}; write e.g. %IX0.3, %QX1.0, %IW2, %QW0, %MW5, %ID1 or %MD0")]
pub struct AddressError {
    /// The text, cut to 64 characters.
    pub text: String,
    /// What is wrong with it.
    pub why: &'static str,
}

impl std::str::FromStr for IecAddress {
    type Err = AddressError;

    fn from_str(text: &str) -> Result<Self, AddressError> {
        let bad = |why: &'static str| AddressError {
            text: text.chars().take(64).collect(),
            why,
        };
        let rest = text
            .strip_prefix('%')
            .ok_or_else(|| bad("it must start with %"))?;
        let mut chars = rest.chars();
        let area = match chars.next() {
            Some('I') => Area::Input,
            Some('Q') => Area::Output,
            Some('M') => Area::Memory,
            _ => return Err(bad("the letter after % must be I, Q or M")),
        };
        let size = match chars.next() {
            Some('X') => Size::Bit,
            Some('W') => Size::Word,
            Some('D') => Size::Double,
            _ => {
                return Err(bad(
                    "the second letter must be X (bit), W (word) or D (double word)",
                ))
            }
        };
        let number = chars.as_str();
        let digits =
            |s: &str| !s.is_empty() && s.len() <= 6 && s.bytes().all(|b| b.is_ascii_digit());
        let index = match size {
            Size::Bit => {
                let (byte, bit) = number
                    .split_once('.')
                    .ok_or_else(|| bad("a bit address needs a byte and a bit, as in %IX0.3"))?;
                if !digits(byte) || !digits(bit) {
                    return Err(bad("the byte and the bit must be numbers"));
                }
                let byte: u32 = byte.parse().map_err(|_| bad("the byte is too large"))?;
                let bit: u32 = bit.parse().map_err(|_| bad("the bit is too large"))?;
                if bit > 7 {
                    return Err(bad("the bit must be 0 to 7"));
                }
                byte * 8 + bit
            }
            Size::Word | Size::Double => {
                if !digits(number) {
                    return Err(bad("the word number must be a number, as in %IW2"));
                }
                number.parse().map_err(|_| bad("the number is too large"))?
            }
        };
        let a = IecAddress { area, size, index };
        if area == Area::Memory && size == Size::Bit {
            return Err(bad(
                "memory bits (%MX) are not mapped; use a memory word, %MW",
            ));
        }
        let (_, first) = a.default_location();
        if first + a.width() > TABLE_LEN {
            return Err(bad(
                "it lies beyond the 65536 bits or registers of a Modbus table",
            ));
        }
        Ok(a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn loc(s: &str) -> (Table, u32) {
        s.parse::<IecAddress>().unwrap().default_location()
    }

    #[test]
    fn the_default_map_is_openplcs() {
        assert_eq!(loc("%IX0.0"), (Table::DiscreteInputs, 0));
        assert_eq!(loc("%IX1.2"), (Table::DiscreteInputs, 10));
        assert_eq!(loc("%QX0.0"), (Table::Coils, 0));
        assert_eq!(loc("%IW0"), (Table::InputRegisters, 0));
        assert_eq!(loc("%QW0"), (Table::HoldingRegisters, 0));
        assert_eq!(loc("%MW0"), (Table::HoldingRegisters, 1024));
        assert_eq!(loc("%ID1"), (Table::InputRegisters, 2));
        assert_eq!(loc("%MD0"), (Table::HoldingRegisters, 2048));
    }

    #[test]
    fn an_address_prints_as_it_was_written() {
        for s in [
            "%IX0.0", "%QX12.7", "%IW3", "%QW0", "%MW9", "%ID2", "%QD0", "%MD4",
        ] {
            assert_eq!(s.parse::<IecAddress>().unwrap().to_string(), s);
        }
    }

    #[test]
    fn malformed_addresses_say_what_to_write() {
        for s in [
            "",
            "IX0.0",
            "%AX0.0",
            "%IY0",
            "%IX0",
            "%IX0.8",
            "%IXa.1",
            "%IW",
            "%IW-1",
            "%MX0.0",
            "%IW65536",
            "%MD31744",
            "%IX99999999.0",
            "%IW1 ",
        ] {
            let e = s.parse::<IecAddress>().unwrap_err();
            assert!(e.to_string().contains("is not an IEC address"), "{s}: {e}");
        }
    }
}
