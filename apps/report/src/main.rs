//! `stride-report`: a walk's report from an lcm-logger log.

fn main() -> std::process::ExitCode {
    stride_node::tool("stride-report", stride_report::run)
}
