//! `stride-usb2can`: a CAN interface on the LCM bus.

use stride_node::{Launch, NoConfig};
use stride_usb2can::{Cli, GatewayApp};

fn main() -> std::process::ExitCode {
    stride_node::main("stride-usb2can", |l: Launch<Cli, NoConfig>| {
        let node = l.start()?;
        let app = GatewayApp::start(&node, l.cli)?;
        node.run(app)
    })
}
