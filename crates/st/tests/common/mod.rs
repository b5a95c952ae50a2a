//! What the tests that drive generated programs share.

use cetratus_st::types::{Elem, Ty};
use cetratus_st::{State, Var};

/// Writes an input given in canonical text.
pub fn write_input(state: &mut State, v: &Var, text: &str) {
    match v.ty {
        Ty::String(cap) => {
            let inner = &text[1..text.len() - 1];
            let mut bytes = Vec::new();
            let mut it = inner.bytes();
            while let Some(b) = it.next() {
                if b != b'$' {
                    bytes.push(b);
                    continue;
                }
                match it.next() {
                    Some(b'$') => bytes.push(b'$'),
                    Some(b'\'') => bytes.push(b'\''),
                    Some(h) => {
                        let l = it.next().unwrap_or(b'0');
                        let hex = [h, l];
                        let s = std::str::from_utf8(&hex).unwrap_or("00");
                        bytes.push(u8::from_str_radix(s, 16).unwrap_or(0));
                    }
                    None => {}
                }
            }
            let n = bytes.len().min(usize::from(cap));
            let at = v.at.text as usize;
            state.text[at..at + 2].copy_from_slice(&(n as u16).to_le_bytes());
            state.text[at + 2..at + 2 + n].copy_from_slice(&bytes[..n]);
        }
        Ty::Elem(e) => {
            let bits = match e {
                Elem::Bool => u64::from(text == "TRUE"),
                Elem::Real => u64::from_str_radix(&text[1..], 16).expect("REAL bits"),
                Elem::Lreal => u64::from_str_radix(&text[1..], 16).expect("LREAL bits"),
                Elem::Time => text[1..].parse::<i64>().expect("TIME ns") as u64,
                e if e.is_signed() => text.parse::<i64>().expect("signed") as u64,
                _ => text.parse::<u64>().expect("unsigned"),
            };
            state.slots[v.at.slots as usize] = bits;
        }
        other => panic!("input of type {other:?}"),
    }
}
