//! `stride-arduino-link`: one Arduino Due joint-controller board on LCM.

use stride_arduino_link::{ArduinoApp, Cli, LinkConfig};
use stride_node::Launch;

fn main() -> std::process::ExitCode {
    stride_node::main("stride-arduino-link", |l: Launch<Cli, LinkConfig>| {
        let node = l.start()?;
        let app = ArduinoApp::start(&node, l.cfg, &l.cli)?;
        node.run(app)
    })
}
