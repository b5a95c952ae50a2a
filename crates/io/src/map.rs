//! The field map: which program signal is which bit or register of which device, bound once at
//! start from the program's declared addresses and the I/O configuration, and the encoding of
//! values into registers and back.

use cetratus_program::{Signal, Type, Value};

use crate::address::{AddressError, Area, IecAddress, Size, Table};
use crate::config::{IoConfig, Scale, WordOrder};
use crate::IoError;

/// One program signal on the field.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    /// Index of the signal in the I/O map's inputs or outputs.
    pub signal: usize,
    /// The signal's name.
    pub name: String,
    /// Its address.
    pub address: IecAddress,
    /// Its type.
    pub ty: Type,
    /// The device that serves it, with the index of the served range and the position of the
    /// signal's first bit or register in that range; `None` for an address no device serves
    /// (memory, or an output only the server shows).
    pub on: Option<(usize, usize, usize)>,
    /// Linear scaling.
    pub scale: Option<Scale>,
    /// An input an HMI may write through the server.
    pub hmi_writable: bool,
}

/// The bound map of a program on a configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldMap {
    /// Inputs with an address, in I/O-map order.
    pub inputs: Vec<Channel>,
    /// Outputs with an address, in I/O-map order.
    pub outputs: Vec<Channel>,
    /// Every input's safe value, in I/O-map order.
    pub safe_inputs: Vec<Value>,
    /// Every output's safe value, in I/O-map order.
    pub safe_outputs: Vec<Value>,
}

fn safe(s: &Signal) -> Value {
    s.safe.unwrap_or(s.ty.zero())
}

impl FieldMap {
    /// Binds a program's signals to the configuration. With a twin (`twin_provides_inputs`),
    /// the twin provides every input and no device may serve one.
    pub fn bind(
        config: &IoConfig,
        inputs: &[Signal],
        outputs: &[Signal],
        twin_provides_inputs: bool,
    ) -> Result<FieldMap, IoError> {
        let mut map = FieldMap {
            inputs: Vec::new(),
            outputs: Vec::new(),
            safe_inputs: inputs.iter().map(safe).collect(),
            safe_outputs: outputs.iter().map(safe).collect(),
        };
        for (i, s) in inputs.iter().enumerate() {
            let Some(text) = &s.address else {
                if twin_provides_inputs {
                    continue;
                }
                return Err(IoError::Unmapped {
                    signal: s.name.clone(),
                    why: "it declares no address; give it the address of a device's input (e.g. address = \"%IX0.0\") in the program".into(),
                });
            };
            let c = channel(config, i, s, text)?;
            if c.address.area == Area::Output {
                return Err(IoError::Unmapped {
                    signal: s.name.clone(),
                    why: format!(
                        "{} is an output address; an input reads %I or %M",
                        c.address
                    ),
                });
            }
            if twin_provides_inputs && c.on.is_some() {
                return Err(IoError::Unmapped {
                    signal: s.name.clone(),
                    why: format!("the twin provides every input, but device `{}` serves {} too; remove the device's input range or --twin", config.devices[c.on.map_or(0, |o| o.0)].name, c.address),
                });
            }
            if c.hmi_writable && twin_provides_inputs {
                return Err(IoError::Unmapped {
                    signal: s.name.clone(),
                    why: format!("{} is marked hmi_writable but the twin provides every input; an input has one source", c.address),
                });
            }
            if c.hmi_writable && c.on.is_some() {
                return Err(IoError::Unmapped {
                    signal: s.name.clone(),
                    why: format!("{} is marked hmi_writable but a field device provides it; an input has one source", c.address),
                });
            }
            if c.address.area == Area::Input
                && c.on.is_none()
                && !c.hmi_writable
                && !twin_provides_inputs
            {
                return Err(IoError::Unmapped {
                    signal: s.name.clone(),
                    why: format!("no device serves {}; add it to a device's `serves` in {}, or mark it hmi_writable", c.address, config.file),
                });
            }
            map.inputs.push(c);
        }
        for (i, s) in outputs.iter().enumerate() {
            let Some(text) = &s.address else { continue };
            let c = channel(config, i, s, text)?;
            if c.address.area != Area::Output {
                return Err(IoError::Unmapped {
                    signal: s.name.clone(),
                    why: format!(
                        "{} is not an output address; an output writes %Q",
                        c.address
                    ),
                });
            }
            map.outputs.push(c);
        }
        // Two signals on one address would fight over it.
        let all = map.inputs.iter().chain(&map.outputs);
        for (k, a) in all.clone().enumerate() {
            if let Some(b) = all.clone().skip(k + 1).find(|b| b.address == a.address) {
                return Err(IoError::Unmapped {
                    signal: b.name.clone(),
                    why: format!(
                        "{} is also the address of `{}`; give each signal its own",
                        b.address, a.name
                    ),
                });
            }
        }
        Ok(map)
    }
}

impl FieldMap {
    /// Appends signals that a live update adds to the I/O map (after the ones bound so far), as
    /// channels of the devices that serve their addresses. Only a signal whose address a device
    /// of `config` serves can be added: an input a device reads, an output a device is written.
    pub fn extend(
        &mut self,
        config: &IoConfig,
        inputs: &[Signal],
        outputs: &[Signal],
    ) -> Result<(), IoError> {
        let mut more = FieldMap {
            inputs: Vec::new(),
            outputs: Vec::new(),
            safe_inputs: inputs.iter().map(safe).collect(),
            safe_outputs: outputs.iter().map(safe).collect(),
        };
        let sides = [
            (inputs, self.safe_inputs.len(), true),
            (outputs, self.safe_outputs.len(), false),
        ];
        for (signals, first, input) in sides {
            for (k, s) in signals.iter().enumerate() {
                let unmapped = |why: String| IoError::Unmapped {
                    signal: s.name.clone(),
                    why,
                };
                let Some(text) = &s.address else {
                    return Err(unmapped(format!("it is new to the running I/O map and declares no address; give it the address of a channel that a device of {} serves", config.file)));
                };
                let c = channel(config, first + k, s, text)?;
                let want = if input { Area::Input } else { Area::Output };
                if c.address.area != want {
                    return Err(unmapped(format!(
                        "{} is not an {} address",
                        c.address,
                        if input { "input (%I)" } else { "output (%Q)" }
                    )));
                }
                if c.on.is_none() {
                    return Err(unmapped(format!("it is new to the running I/O map, and no device of {} serves {}; a live update may add only signals on a configured channel (or restart with the new program)", config.file, c.address)));
                }
                if input && c.hmi_writable {
                    return Err(unmapped(format!("{} is marked hmi_writable but a field device provides it; an input has one source", c.address)));
                }
                if input {
                    more.inputs.push(c);
                } else {
                    more.outputs.push(c);
                }
            }
        }
        let old = self.inputs.iter().chain(&self.outputs);
        let new = more.inputs.iter().chain(&more.outputs);
        for (k, b) in new.clone().enumerate() {
            if let Some(a) = old
                .clone()
                .chain(new.clone().take(k))
                .find(|a| a.address == b.address)
            {
                return Err(IoError::Unmapped {
                    signal: b.name.clone(),
                    why: format!(
                        "{} is also the address of `{}`; give each signal its own",
                        b.address, a.name
                    ),
                });
            }
        }
        self.inputs.append(&mut more.inputs);
        self.outputs.append(&mut more.outputs);
        self.safe_inputs.append(&mut more.safe_inputs);
        self.safe_outputs.append(&mut more.safe_outputs);
        Ok(())
    }
}

fn channel(config: &IoConfig, signal: usize, s: &Signal, text: &str) -> Result<Channel, IoError> {
    let unmapped = |why: String| IoError::Unmapped {
        signal: s.name.clone(),
        why,
    };
    let address: IecAddress = text
        .parse()
        .map_err(|e: AddressError| unmapped(e.to_string()))?;
    match (s.ty, address.size) {
        (Type::Bool, Size::Bit) | (Type::Int | Type::Real, Size::Word | Size::Double) => {}
        (Type::Bool, _) => return Err(unmapped(format!("it is a bool at {address}; a bool needs a bit address (%IX, %QX)"))),
        (_, Size::Bit) => return Err(unmapped(format!("it is {} at the bit address {address}; give it a word (%IW, %QW, %MW) or a double word (%ID, %QD, %MD)", s.ty))),
    }
    let on = config.devices.iter().enumerate().find_map(|(d, dev)| {
        dev.ranges.iter().enumerate().find_map(|(r, range)| {
            range
                .locate(address)
                .map(|n| (d, r, (n - range.offset) as usize))
        })
    });
    let options = config.channels.get(&address).copied().unwrap_or_default();
    Ok(Channel {
        signal,
        name: s.name.clone(),
        address,
        ty: s.ty,
        on,
        scale: options.scale,
        hmi_writable: options.hmi_writable,
    })
}

/// The 32-bit word of two registers in `order`.
pub fn join(regs: [u16; 2], order: WordOrder) -> u32 {
    let (hi, lo) = match order {
        WordOrder::HighFirst => (regs[0], regs[1]),
        WordOrder::LowFirst => (regs[1], regs[0]),
    };
    (u32::from(hi) << 16) | u32::from(lo)
}

/// The two registers of a 32-bit word in `order`.
pub fn split(word: u32, order: WordOrder) -> [u16; 2] {
    let (hi, lo) = ((word >> 16) as u16, word as u16);
    match order {
        WordOrder::HighFirst => [hi, lo],
        WordOrder::LowFirst => [lo, hi],
    }
}

impl Channel {
    /// The value of registers read from the field (one for a word, two for a double word).
    pub fn decode_regs(&self, regs: &[u16], order: WordOrder) -> Value {
        let number = match (self.address.size, self.ty) {
            (Size::Double, Type::Real) if self.scale.is_none() => f64::from(f32::from_bits(join(
                [regs[0], regs.get(1).copied().unwrap_or(0)],
                order,
            ))),
            (Size::Double, _) => {
                f64::from(join([regs[0], regs.get(1).copied().unwrap_or(0)], order) as i32)
            }
            _ => f64::from(regs[0] as i16),
        };
        let v = self.scale.map_or(number, |s| s.to_value(number));
        match self.ty {
            Type::Int => Value::Int(v.round() as i64),
            Type::Real => Value::Real(v),
            Type::Bool => Value::Bool(v != 0.0),
        }
    }

    /// The registers of a value to write (saturated to the register's range).
    pub fn encode_regs(&self, v: Value, order: WordOrder, out: &mut [u16]) {
        let number = match v {
            Value::Bool(b) => f64::from(u8::from(b)),
            Value::Int(i) => i as f64,
            Value::Real(r) => r,
        };
        let raw = self.scale.map_or(number, |s| s.to_raw(number));
        match self.address.size {
            Size::Double if self.ty == Type::Real && self.scale.is_none() => {
                out.copy_from_slice(&split((raw as f32).to_bits(), order));
            }
            // `as` saturates, and NaN becomes 0.
            Size::Double => out.copy_from_slice(&split(raw.round() as i32 as u32, order)),
            _ => out[0] = raw.round() as i16 as u16,
        }
    }

    /// The device table the channel lives in.
    pub fn table(&self) -> Table {
        self.address.default_location().0
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A signal of type `ty` at `address`, with nothing else declared.
    pub(crate) fn signal(name: &str, ty: Type, address: &str) -> Signal {
        Signal {
            name: name.into(),
            ty,
            address: Some(address.into()),
            description: String::new(),
            safe: None,
            initial: ty.zero(),
            retain: false,
        }
    }

    fn config() -> IoConfig {
        IoConfig::parse(
            "io.toml",
            "[[device]]\nname = \"d\"\ntransport = \"modbus-tcp\"\naddress = \"h:502\"\nserves = [{ from = \"%IX0.0\", to = \"%IX0.7\" }, { from = \"%IW0\", to = \"%IW9\" }, { from = \"%QX0.0\", to = \"%QX0.7\" }]\n[[channel]]\naddress = \"%IX1.0\"\nhmi_writable = true\n",
        )
        .unwrap()
    }

    #[test]
    fn signals_bind_to_the_range_that_serves_their_address() {
        let m = FieldMap::bind(
            &config(),
            &[
                signal("A", Type::Bool, "%IX0.2"),
                signal("T", Type::Int, "%IW4"),
                signal("B", Type::Bool, "%IX1.0"),
            ],
            &[signal("Y", Type::Bool, "%QX0.1")],
            false,
        )
        .unwrap();
        assert_eq!(m.inputs[0].on, Some((0, 0, 2)));
        assert_eq!(m.inputs[1].on, Some((0, 1, 4)));
        assert_eq!(m.inputs[2].on, None);
        assert_eq!(m.outputs[0].on, Some((0, 2, 1)));
    }

    #[test]
    fn a_live_update_cannot_add_a_device_input_that_is_marked_hmi_writable() {
        let config = IoConfig::parse(
            "io.toml",
            "[[device]]\nname = \"d\"\ntransport = \"modbus-tcp\"\naddress = \"h:502\"\nserves = [{ from = \"%IX0.0\", to = \"%IX0.7\" }]\n[[channel]]\naddress = \"%IX0.5\"\nhmi_writable = true\n",
        )
        .unwrap();
        let mut m =
            FieldMap::bind(&config, &[signal("A", Type::Bool, "%IX0.0")], &[], false).unwrap();
        let e = m
            .extend(&config, &[signal("B", Type::Bool, "%IX0.5")], &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains('B') && e.contains("hmi_writable"), "{e}");
        assert_eq!(m.inputs.len(), 1, "the map is unchanged");
    }

    #[test]
    fn an_input_no_device_serves_is_refused() {
        let e = FieldMap::bind(&config(), &[signal("A", Type::Bool, "%IX3.0")], &[], false)
            .unwrap_err();
        assert!(e.to_string().contains("no device serves %IX3.0"), "{e}");
        let e =
            FieldMap::bind(&config(), &[signal("A", Type::Bool, "%IW0")], &[], false).unwrap_err();
        assert!(e.to_string().contains("needs a bit address"), "{e}");
        let e = FieldMap::bind(
            &config(),
            &[
                signal("A", Type::Bool, "%IX0.0"),
                signal("B", Type::Bool, "%IX0.0"),
            ],
            &[],
            false,
        )
        .unwrap_err();
        assert!(e.to_string().contains("also the address of `A`"), "{e}");
        let e =
            FieldMap::bind(&config(), &[signal("A", Type::Bool, "%IX0.0")], &[], true).unwrap_err();
        assert!(
            e.to_string().contains("the twin provides every input"),
            "{e}"
        );
    }

    #[test]
    fn words_are_twos_complement_and_double_words_follow_the_word_order() {
        let mut c = FieldMap::bind(&config(), &[signal("T", Type::Int, "%IW4")], &[], false)
            .unwrap()
            .inputs
            .remove(0);
        assert_eq!(
            c.decode_regs(&[0xFFFF], WordOrder::HighFirst),
            Value::Int(-1)
        );
        let mut out = [0u16; 1];
        c.encode_regs(Value::Int(100_000), WordOrder::HighFirst, &mut out);
        assert_eq!(out, [i16::MAX as u16]);
        c.address = "%ID0".parse().unwrap();
        c.ty = Type::Real;
        let mut two = [0u16; 2];
        c.encode_regs(Value::Real(1.5), WordOrder::LowFirst, &mut two);
        assert_eq!(two, split(1.5f32.to_bits(), WordOrder::LowFirst));
        assert_eq!(c.decode_regs(&two, WordOrder::LowFirst), Value::Real(1.5));
        assert_eq!(
            join(
                split(0x1234_5678, WordOrder::HighFirst),
                WordOrder::HighFirst
            ),
            0x1234_5678
        );
    }
}
