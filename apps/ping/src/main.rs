//! `stride-ping`: publishes `stride.ping_t` at a fixed rate and reports the round trips of the
//! echoes `stride-echo` sends back.

use stride_node::{Launch, NoConfig};
use stride_ping::{PingCli, Pinger};

fn main() -> std::process::ExitCode {
    stride_node::main("stride-ping", |l: Launch<PingCli, NoConfig>| {
        let node = l.start()?;
        let app = Pinger::start(&node, l.cli)?;
        node.run(app)
    })
}
