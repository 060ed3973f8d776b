//! `stride`: launch a profile's apps on this host, show the robot's status, send a goal, stop
//! and resume the robot.

use stride_launch::app::{run, Cli};
use stride_node::{Launch, NoConfig};

fn main() -> std::process::ExitCode {
    stride_node::main("stride", |l: Launch<Cli, NoConfig>| run(l))
}
