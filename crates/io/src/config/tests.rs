use super::*;

fn parse(text: &str) -> Result<IoConfig, String> {
    IoConfig::parse("io.toml", text).map_err(|e| e.to_string())
}

const CELL: &str = r#"
start_timeout = "1s"
[[device]]
name = "cell"
transport = "modbus-tcp"
address = "127.0.0.1:15020"
serves = [{ from = "%IX0.0", to = "%IX0.7" }, { from = "%QX0.0", to = "%QX0.7" }]
"#;

#[test]
fn a_device_serves_its_ranges_at_the_default_map() {
    let c = parse(CELL).unwrap();
    assert_eq!(c.start_timeout_us, 1_000_000);
    let d = &c.devices[0];
    assert_eq!(d.unit, 1);
    assert_eq!(d.stale, StalePolicy::Hold);
    assert_eq!(d.ranges[0].table, Table::DiscreteInputs);
    assert_eq!(d.ranges[0].count, 8);
    assert_eq!(d.ranges[1].locate("%QX0.3".parse().unwrap()), Some(3));
    assert_eq!(d.ranges[1].locate("%QX1.0".parse().unwrap()), None);
}

#[test]
fn an_offset_moves_a_range_on_the_device() {
    let c = parse(&CELL.replace(
        "{ from = \"%QX0.0\", to = \"%QX0.7\" }",
        "{ from = \"%QX0.0\", to = \"%QX0.7\", offset = 100 }",
    ))
    .unwrap();
    assert_eq!(
        c.devices[0].ranges[1].locate("%QX0.1".parse().unwrap()),
        Some(101)
    );
}

#[test]
fn overlapping_maps_are_refused_with_their_position() {
    let two = format!("{CELL}\n[[device]]\nname = \"other\"\ntransport = \"modbus-tcp\"\naddress = \"10.0.0.1:502\"\nserves = [{{ from = \"%IX0.7\" }}]\n");
    let e = parse(&two).unwrap_err();
    assert!(e.starts_with("io.toml:13:"), "{e}");
    assert!(
        e.contains("overlapping maps") && e.contains("the same IEC addresses"),
        "{e}"
    );
    let words = "[[device]]\nname = \"d\"\ntransport = \"modbus-tcp\"\naddress = \"h:502\"\nserves = [{ from = \"%IW0\", to = \"%IW3\" }, { from = \"%ID1\" }]\n";
    assert!(parse(words).unwrap_err().contains("overlapping maps"));
    let device_side = "[[device]]\nname = \"d\"\ntransport = \"modbus-tcp\"\naddress = \"h:502\"\nserves = [{ from = \"%IW0\", to = \"%IW3\" }, { from = \"%IW10\", offset = 2 }]\n";
    assert!(parse(device_side)
        .unwrap_err()
        .contains("the same registers of the device"));
}

#[test]
fn ranges_past_the_table_and_memory_ranges_are_refused() {
    let d = |serves: &str| {
        format!("[[device]]\nname = \"d\"\ntransport = \"modbus-tcp\"\naddress = \"h:502\"\nserves = [{serves}]\n")
    };
    assert!(
        parse(&d("{ from = \"%IW0\", to = \"%IW9\", offset = 65530 }"))
            .unwrap_err()
            .contains("runs past")
    );
    assert!(parse(&d("{ from = \"%MW0\" }"))
        .unwrap_err()
        .contains("the PLC's own"));
    assert!(parse(&d("{ from = \"%IX0.3\", to = \"%IX0.1\" }"))
        .unwrap_err()
        .contains("not before it"));
    assert!(parse(&d("{ from = \"%IX0.0\", to = \"%IW1\" }"))
        .unwrap_err()
        .contains("same kind"));
}

#[test]
fn unknown_keys_and_bad_values_say_where_and_what_to_write() {
    let e = parse("[[device]]\nname = \"d\"\ntransport = \"modbus-tcp\"\naddress = \"h:502\"\nserves = []\nspeed = 3\n").unwrap_err();
    assert!(e.starts_with("io.toml:6:"), "{e}");
    let e = parse(&CELL.replace("modbus-tcp", "profinet")).unwrap_err();
    assert!(e.contains("unknown transport `profinet`"), "{e}");
    let e = parse(&CELL.replace("127.0.0.1:15020", "localhost")).unwrap_err();
    assert!(e.contains("is not host:port"), "{e}");
    let e = parse(&format!("{CELL}unit = 300\n")).unwrap_err();
    assert!(e.contains("unit id"), "{e}");
    let e = parse(&format!("{CELL}stale = \"panic\"\n")).unwrap_err();
    assert!(e.contains("\"hold\", \"safe\" or \"fault\""), "{e}");
    let e = parse(&format!("{CELL}timeout = \"0ms\"\n")).unwrap_err();
    assert!(e.contains("longer than 0"), "{e}");
}

#[test]
fn channels_scale_words_and_mark_inputs_writable() {
    let c = parse("[[channel]]\naddress = \"%IW3\"\nscale = { raw = [0, 27648], value = [0.0, 100.0] }\n[[channel]]\naddress = \"%IX1.0\"\nhmi_writable = true\n").unwrap();
    let s = c.channels[&"%IW3".parse().unwrap()].scale.unwrap();
    assert_eq!(s.to_value(13824.0), 50.0);
    assert_eq!(s.to_raw(100.0), 27648.0);
    assert!(c.channels[&"%IX1.0".parse().unwrap()].hmi_writable);
    assert!(
        parse("[[channel]]\naddress = \"%QX0.0\"\nhmi_writable = true\n")
            .unwrap_err()
            .contains("only inputs")
    );
    assert!(parse(
        "[[channel]]\naddress = \"%IX0.0\"\nscale = { raw = [0, 1], value = [0.0, 1.0] }\n"
    )
    .unwrap_err()
    .contains("is a bit"));
    assert!(parse(
        "[[channel]]\naddress = \"%IW0\"\nscale = { raw = [5, 5], value = [0.0, 1.0] }\n"
    )
    .unwrap_err()
    .contains("two different"));
}

#[test]
fn the_server_section_is_checked() {
    let c =
        parse("[server]\nmodbus = \"127.0.0.1:15021\"\nwrite_from = [\"127.0.0.1\"]\n").unwrap();
    let s = c.server.unwrap();
    assert_eq!(s.max_connections, 8);
    assert_eq!(s.write_from.len(), 1);
    assert!(parse("[server]\nmodbus = \"anywhere\"\n")
        .unwrap_err()
        .contains("not an IP address and port"));
    assert!(
        parse("[server]\nmodbus = \"127.0.0.1:1\"\nwrite_from = [\"me\"]\n")
            .unwrap_err()
            .contains("not an IP address")
    );
}

#[test]
fn the_io_section_of_the_local_configuration_is_read_with_its_lines() {
    let text = format!(
        "allow_unsigned = false\n[mqtt]\n[io]\n{}",
        CELL.replace("[[device]]", "[[io.device]]")
    );
    let c = IoConfig::from_local("config.toml", &text).unwrap().unwrap();
    assert_eq!(c.devices[0].at, "config.toml:7:8");
    assert!(IoConfig::from_local("config.toml", "[io]\n")
        .unwrap()
        .is_none());
    let e = IoConfig::from_local("config.toml", "[io]\ndevice = 1\n")
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("config.toml:2:"), "{e}");
}
