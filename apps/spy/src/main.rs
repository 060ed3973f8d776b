//! `stride-spy`: lcm-spy for the terminal.

fn main() -> std::process::ExitCode {
    stride_node::tool("stride-spy", stride_spy::run)
}
