//! `stride-echo`: sends every `stride.ping_t` it receives back on the reply channel.

use stride_node::{Launch, NoConfig};
use stride_ping::{EchoCli, Echoer};

fn main() -> std::process::ExitCode {
    stride_node::main("stride-echo", |l: Launch<EchoCli, NoConfig>| {
        let node = l.start()?;
        let app = Echoer::start(&node, &l.cli)?;
        node.run(app)
    })
}
