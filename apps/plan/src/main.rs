//! `stride-plan`: plans scenes offline and shows the result.

fn main() -> std::process::ExitCode {
    stride_node::tool("stride-plan", stride_plan::run)
}
