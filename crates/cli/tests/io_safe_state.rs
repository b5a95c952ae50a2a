//! The PLC's I/O has one safe state: when the inputs written by OPC UA clients go stale under
//! the `fault` policy, the field devices of the same run are written the safe outputs too, not
//! what the program computes from its safe inputs. A real asyncua client writes the input, a
//! real pymodbus device takes the output, and the real `cetratus run` sits between them
//! (docs/io.md, *Quality*).

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::{stop_with_sigterm, ChildGuard};
use cetratus_testkit::{modbus, opcua};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// `y` follows `x` one cycle later; `y`'s safe value is on, `x`'s off, so that the program
/// on safe inputs drives `y` off while the safe state holds it on.
fn program(dir: &Path) -> std::path::PathBuf {
    std::fs::write(
        dir.join("follow.pnml"),
        "<?xml version=\"1.0\"?>\n<pnml xmlns=\"http://www.pnml.org/version-2009/grammar/pnml\">\n<net id=\"n\" type=\"http://www.pnml.org/version-2009/grammar/ptnet\"><page id=\"g\">\n<place id=\"p\"><initialMarking><text>1</text></initialMarking></place><place id=\"q\"/>\n<transition id=\"on\"/><transition id=\"off\"/>\n<arc id=\"a\" source=\"p\" target=\"on\"/><arc id=\"b\" source=\"on\" target=\"q\"/><arc id=\"c\" source=\"q\" target=\"off\"/><arc id=\"d\" source=\"off\" target=\"p\"/>\n</page></net></pnml>\n",
    )
    .expect("write the net");
    let path = dir.join("follow.toml");
    std::fs::write(
        &path,
        "[program]\nname = \"follow\"\nversion = \"1\"\nnet = \"follow.pnml\"\npolicy = \"step\"\nscan_period = \"10ms\"\n\
         [[input]]\nname = \"x\"\ntype = \"bool\"\naddress = \"%IX0.0\"\n\
         [[output]]\nname = \"y\"\ntype = \"bool\"\naddress = \"%QX0.0\"\nsafe = true\n\
         [guards]\non = \"x\"\noff = \"!x\"\n\
         [[action]]\nplace = \"q\"\nqualifier = \"N\"\ntarget = \"y\"\n",
    )
    .expect("write the program");
    path
}

fn coil(port: u16, want: &str) -> String {
    let end = Instant::now() + Duration::from_secs(30);
    loop {
        let got = modbus::read(port, "coils", 0, 1);
        if got == want || Instant::now() > end {
            return got;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn opc_ua_inputs_stale_under_fault_take_the_field_devices_to_their_safe_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let (device, port, mqtt) = (free_port(), free_port(), free_port());
    let _device = modbus::device(device, &[]);
    let url = format!("opc.tcp://127.0.0.1:{port}");
    let io = dir.path().join("io.toml");
    std::fs::write(
        &io,
        format!(
            "start_timeout = \"1s\"\n\n[[device]]\nname = \"out\"\ntransport = \"modbus-tcp\"\naddress = \"127.0.0.1:{device}\"\nserves = [{{ from = \"%QX0.0\", to = \"%QX0.7\" }}]\n\n[opcua]\nlisten = \"{url}\"\ninputs = true\nstale = \"fault\"\nstale_after = 300\n"
        ),
    )
    .unwrap();
    let plc = ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(program(dir.path()))
            .arg("--io")
            .arg(&io)
            .args(["--json", "--cold", "--plc", "cell", "--no-dashboard"])
            .args(["--mqtt", &format!("127.0.0.1:{mqtt}")])
            .arg("--state-dir")
            .arg(dir.path().join("state"))
            .arg("--config")
            .arg(dir.path().join("config"))
            .stdout(Stdio::piped())
            .stderr(Stdio::null()),
    );
    wait_for_port(port, "the PLC's OPC UA server", Duration::from_secs(60));

    // The client drives y on and off through x; the device follows the program.
    opcua::run(&[
        "run",
        &url,
        "w:cell.Inputs.x:bool:1",
        "wait:cell.Outputs.y:1",
    ]);
    assert_eq!(coil(device, "1"), "1", "the program drove y on");
    opcua::run(&[
        "run",
        &url,
        "w:cell.Inputs.x:bool:0",
        "wait:cell.Outputs.y:0",
    ]);
    assert_eq!(coil(device, "0"), "0", "the program drove y off");

    // The client is gone: after `stale_after` cycles the inputs fault, and the device gets y's
    // safe value (on), though the program on its safe inputs (x off) drives y off.
    assert_eq!(coil(device, "1"), "1", "the field took the safe outputs");
    let summary = stop_with_sigterm(plc);
    let faults = summary["faults"].as_array().expect("faults").clone();
    assert!(
        faults
            .iter()
            .any(|f| f.as_str().unwrap_or("").contains("OPC UA inputs")),
        "{summary}"
    );
}
