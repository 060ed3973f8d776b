//! `stride-footstep-planner`: footstep plans on request, on the LCM bus.

use stride_footstep_planner::app::{run, Cli, PlannerConfig};
use stride_node::Launch;

fn main() -> std::process::ExitCode {
    stride_node::main(
        "stride-footstep-planner",
        |l: Launch<Cli, PlannerConfig>| {
            // --ask is a client beside the planner on the bus: its own name.
            let name = if l.cli.ask.is_some() {
                "stride-footstep-ask"
            } else {
                l.name()
            };
            let node = l.start_as(name)?;
            run(&node, l.cli, l.cfg)
        },
    )
}
