//! Launch profiles (config/launch/*.toml): which apps run on which host, with what command,
//! configuration and bus, in what order, and what happens when one dies. A profile is checked
//! whole before anything starts; every problem is one line.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde::Deserialize;

/// When an app is started again after it ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Restart {
    /// Never.
    Never,
    /// When it failed: a non-zero exit status, a signal, or silence (heartbeats lost).
    #[default]
    OnFailure,
    /// Whenever it ends (unless the launcher stops it).
    Always,
}

/// What a launcher does when a critical app's heartbeat says FAULT (it runs, but cannot do its
/// work: a drive's emergency, a gait that lost its joints' states).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum OnFault {
    /// The system stop; the app runs on and comes back by itself (a bridge re-arms its
    /// drives on the next valid trajectory after `stride resume`).
    #[default]
    Stop,
    /// The system stop, and the app is killed and started again by its restart policy.
    Restart,
}

/// Whether an app belongs to the simulated or the real robot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SimUse {
    /// Runs either way.
    #[default]
    Both,
    /// Only with --sim (a fake device, the simulated world).
    Only,
    /// Only without --sim (a hardware gateway).
    Never,
}

/// One app of a profile, as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AppSpec {
    /// Its name: unique in the profile, the node name of its heartbeats (passed as --name).
    pub name: String,
    /// The program: a stride executable's name (found beside `stride`, then on PATH), or a
    /// path.
    pub command: String,
    /// Its arguments.
    #[serde(default)]
    pub args: Vec<String>,
    /// Its configuration file (passed as --config), relative to the profile's directory.
    pub config: Option<PathBuf>,
    /// The host it runs on (absent: the profile's `host`).
    pub host: Option<String>,
    /// Its LCM URL (absent: the profile's).
    pub lcm_url: Option<String>,
    /// When it is started again.
    #[serde(default)]
    pub restart: Restart,
    /// Apps whose heartbeat must say RUNNING before it starts.
    #[serde(default)]
    pub depends: Vec<String>,
    /// More of them with --sim (the fake devices behind a bridge).
    #[serde(default)]
    pub sim_depends: Vec<String>,
    /// Its death or silence stops the robot (a published system stop), as does a stalled
    /// loop or a fault in its heartbeat.
    #[serde(default)]
    pub critical: bool,
    /// A critical app's fault: "stop" (the system stop) or "restart" (the system stop, and
    /// it is started again by its restart policy).
    #[serde(default)]
    pub on_fault: OnFault,
    /// Whether it runs with --sim, without, or both.
    #[serde(default)]
    pub sim: SimUse,
    /// Arguments added with --sim (e.g. the bus of the fake drives).
    #[serde(default)]
    pub sim_args: Vec<String>,
    /// A stride app: it takes --name and publishes heartbeats. False for other programs
    /// (lcm-logger): those count as running once started.
    #[serde(default = "yes")]
    pub node: bool,
    /// Shutdown stage: lower stages stop first (the gait 1, the bridges 2, the rest 3).
    #[serde(default = "last_stage")]
    pub stage: u8,
    /// How long it may take to end after SIGINT before SIGTERM, then SIGKILL, s.
    #[serde(default = "stop_timeout")]
    pub stop_timeout: f64,
}

fn yes() -> bool {
    true
}

fn last_stage() -> u8 {
    3
}

fn stop_timeout() -> f64 {
    5.0
}

/// Restart backoff and cap.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Backoff {
    /// The first wait before a restart, s; each further restart waits twice as long.
    pub initial: f64,
    /// The longest wait, s.
    pub max: f64,
    /// The most restarts of one app; beyond, it stays down (failed).
    pub max_restarts: u32,
    /// An app that ran this long without failing starts its backoff afresh, s.
    pub reset_after: f64,
}

impl Default for Backoff {
    fn default() -> Backoff {
        Backoff {
            initial: 0.5,
            max: 10.0,
            max_restarts: 5,
            reset_after: 30.0,
        }
    }
}

/// A profile file, as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProfileFile {
    /// What it runs.
    #[serde(default)]
    pub description: String,
    /// The apps' LCM URL unless they give their own.
    pub lcm_url: String,
    /// The host of apps that name none.
    #[serde(default = "local")]
    pub host: String,
    /// How long an app's heartbeats may be silent before it is marked lost, s.
    #[serde(default = "lost_after")]
    pub lost_after: f64,
    /// Restart backoff and cap.
    #[serde(default)]
    pub backoff: Backoff,
    /// Channels of the system stop and of the launcher (the defaults suit every robot).
    #[serde(default)]
    pub channels: Channels,
    /// A host's own bus beside the shared one, by host name: the channels it names stay on
    /// that computer (the robot's full-rate data), the rest crosses to the other hosts.
    #[serde(default)]
    pub local: BTreeMap<String, LocalBus>,
    /// The apps.
    pub app: Vec<AppSpec>,
}

/// A host's own bus (`[local.HOST]`).
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LocalBus {
    /// Its LCM URL: udpm with ttl=0 (it never leaves the computer) on a port of its own.
    pub url: String,
    /// The channels that go there: regular expressions, anchored at both ends.
    pub channels: Vec<String>,
}

fn local() -> String {
    "local".into()
}

fn lost_after() -> f64 {
    3.0
}

/// The channels the launcher uses.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Channels {
    /// The system stop (stride.gait_command_t STOP and RESUME), which the gait and the
    /// bridges obey.
    pub stop: String,
    /// The deputies' reports.
    pub status: String,
    /// Console lines.
    pub console: String,
    /// Orders to the deputies.
    pub order: String,
    /// The heartbeats.
    pub heartbeat: String,
}

impl Default for Channels {
    fn default() -> Channels {
        Channels {
            stop: "STRIDE_STOP".into(),
            status: "STRIDE_LAUNCH_STATUS".into(),
            console: "STRIDE_CONSOLE".into(),
            order: "STRIDE_LAUNCH_ORDER".into(),
            heartbeat: "STRIDE_STATUS".into(),
        }
    }
}

/// An app ready to start: its program found, its arguments complete.
#[derive(Debug, Clone, PartialEq)]
pub struct App {
    /// Its name.
    pub name: String,
    /// The program.
    pub program: PathBuf,
    /// Every argument (--name, --config and the sim arguments included).
    pub args: Vec<String>,
    /// Its host.
    pub host: String,
    /// Its LCM URL.
    pub lcm_url: String,
    /// Its host's own bus, if the profile gives the host one and the app is a stride app.
    pub local: Option<LocalBus>,
    /// When it is started again.
    pub restart: Restart,
    /// What it waits for.
    pub depends: Vec<String>,
    /// Its death stops the robot.
    pub critical: bool,
    /// What its fault does.
    pub on_fault: OnFault,
    /// It publishes heartbeats.
    pub node: bool,
    /// Its shutdown stage.
    pub stage: u8,
    /// SIGINT to SIGTERM to SIGKILL, s.
    pub stop_timeout: f64,
}

/// A checked profile.
#[derive(Debug, Clone)]
pub struct Profile {
    /// Its name (the file's stem).
    pub name: String,
    /// The file as written.
    pub file: ProfileFile,
    /// Every app that runs in this mode (with or without --sim), in start order
    /// (dependencies first).
    pub apps: Vec<App>,
}

/// Checks that `url` is an LCM URL liblcm takes: udpm://ADDRESS:PORT?options with a
/// multicast address, memq:// or file://.
pub fn check_url(url: &str) -> Result<(), String> {
    if url.starts_with("memq://") || url.starts_with("file://") {
        return Ok(());
    }
    let rest = url
        .strip_prefix("udpm://")
        .ok_or_else(|| format!("LCM URL {url:?}: udpm://ADDRESS:PORT?ttl=N, memq:// or file://"))?;
    let (addr, opts) = rest.split_once('?').unwrap_or((rest, ""));
    let (ip, port) = addr
        .rsplit_once(':')
        .ok_or_else(|| format!("LCM URL {url:?}: no port"))?;
    let ip: std::net::Ipv4Addr = ip
        .parse()
        .map_err(|_| format!("LCM URL {url:?}: {ip:?} is not an IPv4 address"))?;
    if !ip.is_multicast() {
        return Err(format!("LCM URL {url:?}: {ip} is not a multicast address"));
    }
    port.parse::<u16>()
        .map_err(|_| format!("LCM URL {url:?}: bad port {port:?}"))?;
    for o in opts.split('&').filter(|o| !o.is_empty()) {
        let (k, v) = o
            .split_once('=')
            .ok_or_else(|| format!("LCM URL {url:?}: option {o:?} is not key=value"))?;
        match k {
            "ttl" | "recv_buf_size" => {
                v.parse::<u32>()
                    .map_err(|_| format!("LCM URL {url:?}: {k}={v:?} is not a number"))?;
            }
            _ => return Err(format!("LCM URL {url:?}: unknown option {k:?}")),
        }
    }
    Ok(())
}

/// The address and port of a udpm URL.
fn udpm_endpoint(url: &str) -> Option<&str> {
    let rest = url.strip_prefix("udpm://")?;
    Some(rest.split_once('?').map_or(rest, |(a, _)| a))
}

/// Checks a host's local bus: a udpm URL with ttl=0 on another address or port than the
/// shared bus, and channel patterns that are regular expressions.
fn check_local(host: &str, bus: &LocalBus, shared: &str) -> Result<(), String> {
    let what = format!("local bus of host {host:?}");
    check_url(&bus.url).map_err(|e| format!("{what}: {e}"))?;
    let endpoint = udpm_endpoint(&bus.url)
        .ok_or_else(|| format!("{what}: {:?} is not a udpm:// URL", bus.url))?;
    if !bus.url.contains("ttl=0") {
        return Err(format!(
            "{what}: {:?} needs ttl=0 (a local bus never leaves its computer)",
            bus.url
        ));
    }
    if udpm_endpoint(shared) == Some(endpoint) {
        return Err(format!(
            "{what}: {endpoint} is the shared bus's address and port (give it a port of its own)"
        ));
    }
    if bus.channels.is_empty() {
        return Err(format!("{what}: no channels"));
    }
    for c in &bus.channels {
        if c.contains(',') {
            return Err(format!(
                "{what}: channel pattern {c:?} has a comma (apps take the list comma-separated)"
            ));
        }
        regex::Regex::new(&format!("^(?:{c})$")).map_err(|e| {
            let why = e.to_string();
            let why = why.lines().last().unwrap_or("").trim().to_owned();
            format!("{what}: channel pattern {c:?} is no regular expression ({why})")
        })?;
    }
    Ok(())
}

/// Finds `command`: a path as given (relative to `root`), else beside `bin_dir`, else on PATH.
pub fn find_program(command: &str, bin_dir: Option<&Path>, root: &Path) -> Option<PathBuf> {
    if command.contains('/') {
        let p = root.join(command);
        return p.is_file().then_some(p);
    }
    if let Some(d) = bin_dir {
        let p = d.join(command);
        if p.is_file() {
            return Some(p);
        }
    }
    std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|d| d.join(command))
            .find(|p| p.is_file())
    })
}

impl Profile {
    /// Reads and checks a profile file; `sim` selects the simulated robot; programs are
    /// looked for beside `bin_dir` first.
    pub fn load(path: &Path, sim: bool, bin_dir: Option<&Path>) -> Result<Profile, String> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| format!("profile {}: {e}", path.display()))?;
        let file: ProfileFile = toml::from_str(&text).map_err(|e| {
            format!(
                "profile {}: {}",
                path.display(),
                e.to_string().trim().replace('\n', " ")
            )
        })?;
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let dir = path.parent().unwrap_or(Path::new("."));
        Profile::check(name, file, dir, sim, bin_dir)
            .map_err(|e| format!("profile {}: {e}", path.display()))
    }

    /// Checks a parsed profile (paths relative to `dir`).
    pub fn check(
        name: String,
        file: ProfileFile,
        dir: &Path,
        sim: bool,
        bin_dir: Option<&Path>,
    ) -> Result<Profile, String> {
        check_url(&file.lcm_url)?;
        let b = &file.backoff;
        if !(file.lost_after > 0.0
            && file.lost_after.is_finite()
            && b.initial > 0.0
            && b.max >= b.initial
            && b.max.is_finite()
            && b.reset_after.is_finite())
        {
            return Err("lost_after and the backoff's times must be positive and finite".into());
        }
        for (host, bus) in &file.local {
            check_local(host, bus, &file.lcm_url)?;
            if !file
                .app
                .iter()
                .any(|a| a.host.as_deref().unwrap_or(&file.host) == host)
            {
                return Err(format!("local bus of host {host:?}: no app runs there"));
            }
        }
        let mut names = BTreeSet::new();
        for a in &file.app {
            // The name is a node's name and a log file's: letters, digits, '-', '_' and '.'
            // (not first), nothing that leaves --log-dir.
            let ok = a
                .name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'));
            if a.name.is_empty() || a.name.len() > 64 || !ok || a.name.starts_with('.') {
                return Err(format!(
                    "app {:?}: a name of letters, digits, '-', '_' and '.' (not first), at \
                     most 64, is needed",
                    a.name
                ));
            }
            if !names.insert(a.name.as_str()) {
                return Err(format!("app {:?} is named twice", a.name));
            }
        }
        let runs = |a: &AppSpec| match a.sim {
            SimUse::Both => true,
            SimUse::Only => sim,
            SimUse::Never => !sim,
        };
        let running: BTreeSet<&str> = file
            .app
            .iter()
            .filter(|a| runs(a))
            .map(|a| a.name.as_str())
            .collect();
        for a in &file.app {
            let extra = if sim { &a.sim_depends[..] } else { &[] };
            for d in a.depends.iter().chain(extra) {
                if !names.contains(d.as_str()) {
                    return Err(format!(
                        "app {:?} depends on {d:?}, which is no app",
                        a.name
                    ));
                }
                if runs(a) && !running.contains(d.as_str()) {
                    return Err(format!(
                        "app {:?} depends on {d:?}, which does not run {}",
                        a.name,
                        if sim { "with --sim" } else { "without --sim" }
                    ));
                }
            }
        }
        let mut all = file.app.clone();
        for a in &mut all {
            if sim {
                a.depends.extend(a.sim_depends.iter().cloned());
            }
        }
        let order = start_order(&all)?;
        let root = dir.join("../..");
        let mut apps = Vec::new();
        for i in order {
            let a = &all[i];
            if !runs(a) {
                continue;
            }
            let program = find_program(&a.command, bin_dir, &root).ok_or_else(|| {
                format!(
                    "app {:?}: program {:?} not found (beside stride, or on PATH){}",
                    a.name,
                    a.command,
                    if a.command.starts_with("stride") {
                        ": build it with cargo build --release"
                    } else {
                        ""
                    }
                )
            })?;
            let lcm_url = a.lcm_url.clone().unwrap_or_else(|| file.lcm_url.clone());
            check_url(&lcm_url).map_err(|e| format!("app {:?}: {e}", a.name))?;
            if !(a.stop_timeout > 0.0 && a.stop_timeout.is_finite()) {
                return Err(format!("app {:?}: stop_timeout must be positive", a.name));
            }
            let mut args = Vec::new();
            if a.node {
                args.extend(["--name".to_string(), a.name.clone()]);
            }
            if let Some(c) = &a.config {
                let p = dir.join(c);
                if !p.is_file() {
                    return Err(format!(
                        "app {:?}: configuration {} not found",
                        a.name,
                        p.display()
                    ));
                }
                args.extend(["--config".to_string(), p.to_string_lossy().into_owned()]);
            }
            args.extend(a.args.iter().cloned());
            if sim {
                args.extend(a.sim_args.iter().cloned());
            }
            let host = a.host.clone().unwrap_or_else(|| file.host.clone());
            let local = file.local.get(&host).filter(|_| a.node).cloned();
            if let Some(l) = &local {
                if lcm_url == l.url {
                    return Err(format!(
                        "app {:?}: its LCM URL is its host's local bus ({})",
                        a.name, l.url
                    ));
                }
            }
            apps.push(App {
                name: a.name.clone(),
                program,
                args,
                host,
                lcm_url,
                local,
                restart: a.restart,
                depends: a.depends.clone(),
                critical: a.critical,
                on_fault: a.on_fault,
                node: a.node,
                stage: a.stage,
                stop_timeout: a.stop_timeout,
            });
        }
        Ok(Profile { name, file, apps })
    }

    /// The hosts the profile's apps run on.
    pub fn hosts(&self) -> BTreeSet<String> {
        self.apps.iter().map(|a| a.host.clone()).collect()
    }
}

/// The apps' indices with every app after what it depends on (stable: file order otherwise),
/// or the cycle.
pub fn start_order(apps: &[AppSpec]) -> Result<Vec<usize>, String> {
    let index: BTreeMap<&str, usize> = apps
        .iter()
        .enumerate()
        .map(|(i, a)| (a.name.as_str(), i))
        .collect();
    // 0: not visited, 1: on the path, 2: done.
    let mut mark = vec![0u8; apps.len()];
    let mut order = Vec::new();
    fn visit(
        i: usize,
        apps: &[AppSpec],
        index: &BTreeMap<&str, usize>,
        mark: &mut [u8],
        order: &mut Vec<usize>,
        path: &mut Vec<usize>,
    ) -> Result<(), String> {
        match mark[i] {
            2 => return Ok(()),
            1 => {
                let from = path.iter().position(|&p| p == i).unwrap_or(0);
                let mut cycle: Vec<&str> = path[from..]
                    .iter()
                    .map(|&p| apps[p].name.as_str())
                    .collect();
                cycle.push(&apps[i].name);
                return Err(format!("a dependency cycle: {}", cycle.join(" -> ")));
            }
            _ => {}
        }
        mark[i] = 1;
        path.push(i);
        for d in &apps[i].depends {
            if let Some(&j) = index.get(d.as_str()) {
                visit(j, apps, index, mark, order, path)?;
            }
        }
        path.pop();
        mark[i] = 2;
        order.push(i);
        Ok(())
    }
    for i in 0..apps.len() {
        visit(i, apps, &index, &mut mark, &mut order, &mut Vec::new())?;
    }
    Ok(order)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn profile(text: &str, sim: bool) -> Result<Profile, String> {
        let dir = tempfile::tempdir().unwrap();
        let bin = dir.path().join("bin");
        std::fs::create_dir(&bin).unwrap();
        for p in ["stride-a", "stride-b", "stride-c"] {
            std::fs::write(bin.join(p), "").unwrap();
        }
        std::fs::write(dir.path().join("a.toml"), "").unwrap();
        let file: ProfileFile = toml::from_str(text).map_err(|e| e.to_string())?;
        Profile::check("t".into(), file, dir.path(), sim, Some(&bin))
    }

    const HEAD: &str = "lcm_url = \"udpm://239.255.76.67:7667?ttl=0\"\n";

    #[test]
    fn a_good_profile_starts_dependencies_first_with_their_arguments() {
        let p = profile(
            &format!(
                "{HEAD}[[app]]\nname = \"x\"\ncommand = \"stride-a\"\ndepends = [\"y\"]\n\
                 config = \"a.toml\"\n\
                 [[app]]\nname = \"y\"\ncommand = \"stride-b\"\nsim_args = [\"--bus\", \"lcm:l\"]\n\
                 [[app]]\nname = \"z\"\ncommand = \"stride-c\"\nsim = \"only\"\n"
            ),
            true,
        )
        .unwrap();
        let names: Vec<&str> = p.apps.iter().map(|a| a.name.as_str()).collect();
        assert_eq!(names, ["y", "x", "z"]);
        assert_eq!(p.apps[0].args, ["--name", "y", "--bus", "lcm:l"]);
        assert_eq!(p.apps[1].args[..3], ["--name", "x", "--config"]);
        assert_eq!(p.apps[1].host, "local");
        let real = profile(
            &format!(
                "{HEAD}[[app]]\nname = \"y\"\ncommand = \"stride-b\"\nsim_args = [\"--bus\", \"lcm:l\"]\n\
                 [[app]]\nname = \"z\"\ncommand = \"stride-c\"\nsim = \"only\"\n"
            ),
            false,
        )
        .unwrap();
        assert_eq!(real.apps.len(), 1);
        assert_eq!(real.apps[0].args, ["--name", "y"]);
    }

    #[test]
    fn a_hosts_local_bus_goes_to_its_stride_apps_only() {
        let p = profile(
            &format!(
                "{HEAD}[[app]]\nname = \"x\"\ncommand = \"stride-a\"\nhost = \"robot\"\n\
                 [[app]]\nname = \"log\"\ncommand = \"stride-b\"\nhost = \"robot\"\nnode = false\n\
                 [[app]]\nname = \"y\"\ncommand = \"stride-c\"\nhost = \"laptop\"\n\
                 [local.robot]\nurl = \"udpm://239.255.76.67:7668?ttl=0\"\nchannels = [\"JOINT_.*\"]\n"
            ),
            false,
        )
        .unwrap();
        let local = |n: &str| p.apps.iter().find(|a| a.name == n).unwrap().local.clone();
        assert_eq!(
            local("x").map(|l| (l.url, l.channels)),
            Some((
                "udpm://239.255.76.67:7668?ttl=0".to_string(),
                vec!["JOINT_.*".to_string()]
            ))
        );
        assert_eq!(local("log"), None);
        assert_eq!(local("y"), None);
    }

    #[test]
    fn every_profile_error_is_one_clear_line() {
        let cases = [
            (
                format!("{HEAD}[[app]]\nname = \"x\"\ncommand = \"stride-nothing\"\n"),
                "program \"stride-nothing\" not found",
            ),
            (
                format!("{HEAD}[[app]]\nname = \"x\"\ncommand = \"stride-a\"\nconfig = \"no.toml\"\n"),
                "no.toml not found",
            ),
            (
                format!(
                    "{HEAD}[[app]]\nname = \"x\"\ncommand = \"stride-a\"\n\
                     [[app]]\nname = \"x\"\ncommand = \"stride-b\"\n"
                ),
                "named twice",
            ),
            (
                "lcm_url = \"udpm://10.0.0.1:7667?ttl=0\"\n[[app]]\nname = \"x\"\ncommand = \"stride-a\"\n"
                    .to_string(),
                "not a multicast address",
            ),
            (
                format!(
                    "{HEAD}[[app]]\nname = \"x\"\ncommand = \"stride-a\"\nlcm_url = \"udpm://239.1.1.1:7667?tll=1\"\n"
                ),
                "unknown option",
            ),
            (
                format!(
                    "{HEAD}[[app]]\nname = \"x\"\ncommand = \"stride-a\"\ndepends = [\"z\"]\n\
                     [[app]]\nname = \"y\"\ncommand = \"stride-b\"\ndepends = [\"x\"]\n\
                     [[app]]\nname = \"z\"\ncommand = \"stride-c\"\ndepends = [\"y\"]\n"
                ),
                "a dependency cycle: x -> z -> y -> x",
            ),
            (
                format!("{HEAD}[[app]]\nname = \"x\"\ncommand = \"stride-a\"\ndepends = [\"w\"]\n"),
                "depends on \"w\", which is no app",
            ),
            (
                format!(
                    "{HEAD}[[app]]\nname = \"x\"\ncommand = \"stride-a\"\ndepends = [\"y\"]\n\
                     [[app]]\nname = \"y\"\ncommand = \"stride-b\"\nsim = \"only\"\n"
                ),
                "which does not run without --sim",
            ),
            (
                format!(
                    "{HEAD}[[app]]\nname = \"x\"\ncommand = \"stride-a\"\n\
                     [local.local]\nurl = \"udpm://239.255.76.67:7668?ttl=1\"\nchannels = [\"J\"]\n"
                ),
                "needs ttl=0",
            ),
            (
                format!(
                    "{HEAD}[[app]]\nname = \"x\"\ncommand = \"stride-a\"\n\
                     [local.local]\nurl = \"udpm://239.255.76.67:7667?ttl=0\"\nchannels = [\"J\"]\n"
                ),
                "is the shared bus's address and port",
            ),
            (
                format!(
                    "{HEAD}[[app]]\nname = \"x\"\ncommand = \"stride-a\"\n\
                     [local.local]\nurl = \"udpm://239.255.76.67:7668?ttl=0\"\nchannels = [\"J(\"]\n"
                ),
                "channel pattern \"J(\" is no regular expression",
            ),
            (
                format!(
                    "{HEAD}[[app]]\nname = \"x\"\ncommand = \"stride-a\"\n\
                     [local.robot]\nurl = \"udpm://239.255.76.67:7668?ttl=0\"\nchannels = [\"J\"]\n"
                ),
                "local bus of host \"robot\": no app runs there",
            ),
        ];
        for (text, want) in cases {
            let e = profile(&text, false).unwrap_err();
            assert!(e.contains(want), "{e:?} lacks {want:?}");
            assert!(!e.contains('\n'), "{e:?}");
        }
    }

    /// D11 of the reliability findings: an app named `../../../escaped` started, and its log
    /// was written three levels outside --log-dir.
    #[test]
    fn an_app_name_that_would_leave_the_log_dir_is_refused() {
        for bad in ["../../../escaped", "a/b", "..", ".hidden", "", "x y", "é"] {
            let text = format!("{HEAD}[[app]]\nname = {bad:?}\ncommand = \"stride-a\"\n");
            let e = profile(&text, false).unwrap_err();
            assert!(e.contains("a name of letters"), "{bad:?}: {e}");
        }
        let ok = format!("{HEAD}[[app]]\nname = \"left-leg_2.a\"\ncommand = \"stride-a\"\n");
        assert!(profile(&ok, false).is_ok());
    }
}
