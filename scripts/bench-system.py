#!/usr/bin/env python3
"""scripts/bench system, run inside the private network namespace scripts/bench makes.

Two computers are made of network namespaces, as the multi-host tests make them: "robot" and
"laptop" on one bridge (one Wi-Fi: multicast passes), or each on its own subnet behind this
namespace as a router (unicast passes, multicast does not). Then, side by side in one run:

- the Zenoh hop: LCM round trips and a one-way stream between the two computers, directly
  over multicast (one Wi-Fi) and through two stride-zenoh-bridges (routed); the bridged round
  trip crosses two bridges each way, so a hop adds half of the difference;
- each app's CPU at idle: Archie's simulated robot launched (stride launch archie --sim) and
  left standing, the deputy's 1 Hz status of each app averaged over a window;
- the stages of a replanned walk, on one host and split (the planner on the laptop, the rest
  on the robot, one Wi-Fi): Archie's case 7 walked to its goal while lcm-logger records, each
  stage's time from the headers of the messages that begin and end it (one clock: the
  namespaces share the machine's).

Prints the tables (Markdown) on stdout; progress on stderr.
"""

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
REL = ROOT / "target" / "release"
PERF = REL / "examples" / "lcm_perf"


def log(*a):
    print(*a, file=sys.stderr, flush=True)


def sh(cmd):
    r = subprocess.run(["sh", "-c", cmd], capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"{cmd}: {r.stderr.strip()}")


class Hosts:
    """robot and laptop namespaces, bridged (one Wi-Fi) or routed (two subnets)."""

    def __init__(self, routed, tag):
        self.routed = routed
        self.tag = tag
        self.names = ["robot", "laptop"]
        # A run killed before its close left its namespaces' names behind (/run/netns outlives
        # the sandbox's network namespace): they would refuse these.
        self.close()
        if routed:
            sh("sysctl -qw net.ipv4.ip_forward=1")
        else:
            sh(f"ip link add bench{tag} type bridge mcast_snooping 0 && ip link set bench{tag} up")
        for i, name in enumerate(self.names):
            ns, veth = self.ns(name), f"v{name[0]}{tag}"
            sh(f"ip netns add {ns} && ip link add {veth} type veth peer name eth0 netns {ns} && "
               f"ip -n {ns} link set lo up && ip -n {ns} link set eth0 up")
            if routed:
                n = i + 1
                sh(f"ip addr add 10.78.{n}.1/24 dev {veth} && ip link set {veth} up && "
                   f"ip -n {ns} addr add 10.78.{n}.2/24 dev eth0 && "
                   f"ip -n {ns} route add default via 10.78.{n}.1")
            else:
                sh(f"ip link set {veth} master bench{tag} up && "
                   f"ip -n {ns} addr add 10.79.0.{i + 1}/24 dev eth0")
            sh(f"ip -n {ns} route add 224.0.0.0/4 dev eth0")

    def ns(self, name):
        return f"bench-{name}-{self.tag}"

    def on(self, name, *cmd):
        return ["ip", "netns", "exec", self.ns(name), *map(str, cmd)]

    def close(self):
        for name in self.names:
            subprocess.run(["ip", "link", "del", f"v{name[0]}{self.tag}"], capture_output=True)
            subprocess.run(["ip", "netns", "del", self.ns(name)], capture_output=True)
        subprocess.run(["ip", "link", "del", f"bench{self.tag}"], capture_output=True)


URL = "udpm://239.255.76.67:7667?ttl=1&recv_buf_size=4194304"


def profile_url(profile):
    """The LCM URL a launch profile names."""
    import tomllib
    return tomllib.loads(profile.read_text())["lcm_url"]


def bridge_config(path, bus, listen, connect, certs, name):
    """A bridge of the link as shipped: QUIC with TLS both ways with `name`'s certificate from `certs`
    (scripts/zenoh-certs), the operator's password checked by the robot."""
    auth = (f'users_file = "{certs}/robot-users.txt"\n' if name == "robot" else
            f'user = "operator"\npassword_file = "{certs}/operator.password"\n')
    path.write_text(
        f'bus = "{bus}"\nin = ["PERF_.*"]\n[zenoh]\nlisten = {json.dumps(listen)}\n'
        f'connect = {json.dumps(connect)}\n'
        f'[zenoh.tls]\nca = "{certs}/ca.pem"\ncertificate = "{certs}/{name}.pem"\n'
        f'key = "{certs}/{name}-key.pem"\n[zenoh.auth]\n{auth}'
        f'[[out]]\npattern = "PERF_.*"\n')


def perf_runs(hosts, sizes, count, streams):
    """Round trips (laptop pings, robot pongs) and streams (laptop sends, robot sinks)."""
    out = {"latency": {}, "throughput": {}}
    for size in sizes:
        pong = subprocess.Popen(hosts.on("robot", PERF, "pong", URL))
        time.sleep(0.3)
        r = subprocess.run(hosts.on("laptop", PERF, "ping", URL, size, count),
                           capture_output=True, text=True, timeout=300)
        pong.kill()
        pong.wait()
        m = dict(kv.split("=", 1) for kv in r.stdout.split() if "=" in kv)
        if "rtt_ns" not in m:
            raise SystemExit(f"lcm_perf ping {size}: {r.stdout}{r.stderr}")
        rtt = [int(x) / 1e3 for x in m["rtt_ns"].split(",") if x]
        out["latency"][size] = {"rtt": rtt, "lost": int(m["lost"])}
    for size, n, window in streams:
        sink = subprocess.Popen(hosts.on("robot", PERF, "sink", URL))
        time.sleep(0.3)
        r = subprocess.run(hosts.on("laptop", PERF, "source", URL, size, n, window),
                           capture_output=True, text=True, timeout=300)
        sink.kill()
        sink.wait()
        m = dict(kv.split("=", 1) for kv in r.stdout.split() if "=" in kv)
        out["throughput"][(size, window)] = m
    return out


def pct(v, p):
    v = sorted(v)
    if not v:
        return float("nan")
    k = max(1, min(len(v), int(p / 100 * len(v) + 0.999999)))
    return v[k - 1]


def zenoh_bench(count):
    sizes = [100, 10_000]
    streams = [(100, 20_000, 8), (100, 20_000, 64), (10_000, 5_000, 8), (10_000, 5_000, 32)]
    log(f"zenoh: direct LCM between two hosts on one bridge ({count} round trips a size)")
    direct_hosts = Hosts(False, "d")
    try:
        direct = perf_runs(direct_hosts, sizes, count, streams)
    finally:
        direct_hosts.close()
    log("zenoh: the same through two stride-zenoh-bridges, two subnets routed")
    routed = Hosts(True, "z")
    procs = []
    try:
        tmp = Path(tempfile.mkdtemp())
        certs = tmp / "certs"
        subprocess.run([ROOT / "scripts" / "zenoh-certs", certs, "10.78.1.2"], check=True,
                       capture_output=True)
        bridge_config(tmp / "robot.toml", "robot", ["quic/10.78.1.2:7447"], [], certs, "robot")
        bridge_config(tmp / "laptop.toml", "laptop", [], ["quic/10.78.1.2:7447"], certs,
                      "operator")
        for host in ["robot", "laptop"]:
            procs.append(subprocess.Popen(
                routed.on(host, REL / "stride-zenoh-bridge", "--lcm-url", URL, "--log-level",
                          "warn", "--config", tmp / f"{host}.toml")))
        time.sleep(2.0)
        bridged = perf_runs(routed, sizes, count, streams)
    finally:
        for p in procs:
            p.terminate()
            p.wait()
        routed.close()
    rows = ["| message | direct p50 | direct p99 | bridged p50 | bridged p99 | a hop adds, p99 "
            "| bar | verdict |", "|---|---|---|---|---|---|---|---|"]
    verdicts = []
    for size in sizes:
        d, b = direct["latency"][size]["rtt"], bridged["latency"][size]["rtt"]
        hop = (pct(b, 99) - pct(d, 99)) / 2
        ok = hop < 1000
        verdicts.append(ok)
        rows.append(f"| {size} B round trip | {pct(d, 50):.0f} µs | {pct(d, 99):.0f} µs | "
                    f"{pct(b, 50):.0f} µs | {pct(b, 99):.0f} µs | {hop:.0f} µs | < 1000 µs | "
                    f"{'meets' if ok else 'MISSES'} |")
    rows += ["", "| stream | direct | bridged | bridged / direct | not acknowledged, bridged "
             "| bar | verdict |", "|---|---|---|---|---|---|---|"]
    for size, n, window in streams:
        d, b = direct["throughput"][(size, window)], bridged["throughput"][(size, window)]
        dm, bm = float(d.get("msgs_per_s", "nan")), float(b.get("msgs_per_s", "nan"))
        # A message lost stalls the window: the bridges carry every one or fail.
        ok = b.get("lost") == "0"
        verdicts.append(ok)
        rows.append(f"| {n} × {size} B, {window} in flight | {dm:,.0f} msg/s "
                    f"({dm * size / 1e6:.1f} MB/s) | {bm:,.0f} msg/s ({bm * size / 1e6:.1f} MB/s)"
                    f" | {bm / dm:.2f} | {b.get('lost', '?')} of {n} | none lost | "
                    f"{'meets' if ok else 'MISSES'} |")
    lost = {s: (direct["latency"][s]["lost"], bridged["latency"][s]["lost"]) for s in sizes}
    rows.append("")
    rows.append("Round trips lost (direct, bridged): " +
                ", ".join(f"{s} B {a}, {b}" for s, (a, b) in lost.items()) + ".")
    return "\n".join(rows), all(verdicts)


def idle_cpu(window):
    """Each app of Archie's simulated robot standing: CPU from the deputy's heartbeats."""
    log(f"idle: stride launch archie --sim, standing; CPU over {window} s")
    profile = ROOT / "config/launch/archie.toml"
    url = profile_url(profile)
    env = dict(os.environ, PATH=f"{REL}:{os.environ['PATH']}")
    logs = Path(tempfile.mkdtemp())
    launch = subprocess.Popen(
        [REL / "stride", "--lcm-url", url, "--log-level", "warn", "launch", profile, "--sim",
         "--log-dir", logs],
        env=env, stdout=subprocess.DEVNULL)
    def reports(secs):
        return [m for _, m in spy_echo("--lcm-url", url, "--channel", "STRIDE_LAUNCH_STATUS",
                                       "--duration", secs, timeout=secs + 30)]

    try:
        # Every app running, then settled (the legs at the gait's pose, the planner's world in).
        deadline = time.time() + 120
        while time.time() < deadline:
            if launch.poll() is not None:
                raise SystemExit(f"stride launch archie --sim ended: {launch.returncode}")
            last = reports(2)
            apps = last[-1]["apps"] if last else []
            if apps and all(a["state"] == 2 for a in apps):
                break
        time.sleep(15)
        pids = {a["name"]: a["pid"] for a in reports(2)[-1]["apps"]}
        # The deputy (stride launch) is one of the robot's processes too.
        pids[DEPUTY] = launch.pid
        before, t0 = {n: cpu_ns(p) for n, p in pids.items()}, time.monotonic()
        samples = {}
        for m in reports(window):
            for a in m["apps"]:
                samples.setdefault(a["name"], []).append(100.0 * float(a["cpu"]))
        after, t1 = {n: cpu_ns(p) for n, p in pids.items()}, time.monotonic()
    finally:
        launch.send_signal(2)
        try:
            launch.wait(timeout=60)
        except subprocess.TimeoutExpired:
            launch.kill()
    rows = ["| app | CPU at idle (all its threads' time on a CPU over the window) | "
            "the deputy's 1 Hz reports: mean, max | bar | verdict |", "|---|---|---|---|---|"]
    ok_all = True
    for name in sorted(pids):
        share = 100.0 * (after[name] - before[name]) / 1e9 / (t1 - t0)
        ok = share < 1.0
        ok_all &= ok
        v = samples.get(name)
        reported = f"{statistics.mean(v):.2f} %, {max(v):.2f} %" if v else "-"
        rows.append(f"| {name} | {share:.2f} % | {reported} | "
                    f"< 1 % | {'meets' if ok else 'MISSES'} |")
    return "\n".join(rows), ok_all


DEPUTY = "(stride launch, the deputy)"


def cpu_ns(pid):
    """The time all threads of process `pid` have spent on a CPU, ns (the scheduler's own
    count: /proc/PID/task/*/schedstat)."""
    total = 0
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            total += int((task / "schedstat").read_text().split()[0])
        except (OSError, ValueError, IndexError):
            pass
    return total


STAGE_CHANNELS = ("WALK_GOAL|FOOTSTEP_PLAN_REQUEST|FOOTSTEP_PLAN|GAIT_STATUS|"
                  "JOINT_TRAJECTORY_LEFT_LEG|OBSTACLES|STRIDE_LAUNCH_STATUS")


def spy_echo(*args, timeout=300):
    """(channel, message) of each JSON line `stride-spy echo ARGS` prints, in order."""
    r = subprocess.run([REL / "stride-spy", "echo", *map(str, args)], capture_output=True,
                       text=True, timeout=timeout)
    out = []
    for line in r.stdout.splitlines():
        try:
            m = json.loads(line)
        except ValueError:
            continue
        out.append((m["channel"], m["message"]))
    return out


def decoded(log):
    """(channel, message) of a log's stage channels, by stride-spy, in the order of their
    header times (with the robot's local bus's log beside it, when there is one)."""
    msgs = spy_echo("--log", log, "--channel", STAGE_CHANNELS)
    local = local_log(log)
    if local.exists():
        msgs += spy_echo("--log", local, "--channel", STAGE_CHANNELS)
        msgs.sort(key=lambda cm: cm[1]["header"]["utime"])
    return msgs


def local_log(log):
    """Where the log of the robot's local bus goes beside `log`."""
    return log.with_name(log.stem + "-local" + log.suffix)


def stages_of(log):
    """Each plan's stages, ms: request to plan (the planner, with the bus both ways), plan to
    taken (the gait's pattern, joints and checks: its status says accepted), plan to its first
    set-point (the trajectory chunk that follows that status)."""
    requests, answered = {}, set()
    out = {"request→plan": [], "plan→taken": [], "plan→first set-point": []}
    accepted = None
    pending = []  # plans not yet taken: their header times
    taken = None  # the plan just taken: its header time
    for ch, m in decoded(log):
        t = m["header"]["utime"] / 1e3
        if ch == "FOOTSTEP_PLAN_REQUEST":
            requests[m["request_id"]] = t
        elif ch == "FOOTSTEP_PLAN":
            rid = m["request_id"]
            if rid in requests and m["status"] == 0:
                # The first answer: a later one is the planner's own replan when the world
                # changed (a box appeared), the obstacle stages' affair.
                if rid not in answered:
                    answered.add(rid)
                    out["request→plan"].append(t - requests[rid])
                pending.append(t)
        elif ch == "GAIT_STATUS":
            a = m["accepted"]
            if accepted is not None and a > accepted and pending:
                out["plan→taken"].append(t - pending[-1])
                taken = pending[-1]
            pending = []
            accepted = a
        elif ch == "JOINT_TRAJECTORY_LEFT_LEG" and taken is not None:
            out["plan→first set-point"].append(t - taken)
            taken = None
    return out


def goal_stages_of(log):
    """Each goal sent to a standing robot, ms: to the gait's first request, and to the first
    set-point (the trajectory chunk after the status that says its first plan taken)."""
    out = {"goal→first request": [], "goal→first set-point": []}
    goal, asked, accepted, taken = None, False, None, False
    for ch, m in decoded(log):
        t = m["header"]["utime"] / 1e3
        if ch == "WALK_GOAL":
            goal, asked, taken = t, False, False
        elif ch == "FOOTSTEP_PLAN_REQUEST" and goal is not None and not asked:
            out["goal→first request"].append(t - goal)
            asked = True
        elif ch == "GAIT_STATUS":
            a = m["accepted"]
            if goal is not None and accepted is not None and a > accepted:
                taken = True
            accepted = a
        elif ch == "JOINT_TRAJECTORY_LEFT_LEG" and goal is not None and taken:
            out["goal→first set-point"].append(t - goal)
            goal = None
    return out


def cpu_of(log):
    """Each app's mean CPU (% of a core) in the deputies' reports of a log."""
    samples = {}
    for ch, m in spy_echo("--log", log, "--channel", "STRIDE_LAUNCH_STATUS"):
        for a in m["apps"]:
            samples.setdefault(a["name"], []).append(100.0 * float(a["cpu"]))
    return {k: statistics.mean(v) for k, v in samples.items() if v}


def edited_profile(profile, sim_config):
    """A copy of `profile` whose simulated world reads `sim_config` (every other path kept)."""
    tmp = Path(tempfile.mkdtemp())
    text = profile.read_text().replace('"../sim-archie.toml"', f'"{sim_config}"')
    text = text.replace('"../', f'"{ROOT}/config/')
    out = tmp / profile.name
    out.write_text(text)
    return out


BOX_EVERY = 8  # touch-downs between boxes: the last one passed before the next appears


def obstacle_world(trials, length):
    """A flat corridor `length` m long (no obstacle at the start) and the simulated world's
    configuration for it: a 0.25 x 0.25 x 1 m box appears 1 m ahead of the pelvis toward the
    goal at every `BOX_EVERY`th touch-down from the fourth, `trials` of them; perception
    without delay (the obstacles' header is when they were seen)."""
    tmp = Path(tempfile.mkdtemp())
    scene = tmp / "corridor.toml"
    goal = length - 1.0
    scene.write_text(
        'name = "bench-corridor"\n'
        'description = "a flat corridor; boxes appear ahead of the robot as it walks"\n'
        'reference = "scripts/bench system"\n'
        'start = { x = 0.0, y = 0.0, yaw = 0.0 }\n'
        f'goal = {{ x = {goal}, y = 0.0 }}\n'
        f'[map]\nx = [-1.0, {length}]\ny = [-4.0, 4.0]\n')
    text = (ROOT / "config/sim-archie.toml").read_text()
    text = re.sub(r'^scene = .*$', f'scene = "{scene}"', text, count=1, flags=re.M)
    text = re.sub(r'^robot_file = .*$', f'robot_file = "{ROOT}/config/robots/archie.toml"', text,
                  count=1, flags=re.M)
    text = re.sub(r'^delay = .*$', 'delay = 0.0', text, count=1, flags=re.M)
    for k in range(trials):
        text += (f"\n[[appear]]\nafter_touchdowns = {4 + BOX_EVERY * k}\nahead = 1.0\n"
                 f"toward = [{goal}, 0.0]\nsize = [0.25, 0.25, 1.0]\n")
    cfg = tmp / "sim.toml"
    cfg.write_text(text)
    return cfg


def obstacle_stages_of(log):
    """Each box's stages, ms: seen (the first obstacle list with its id) to the planner's first
    plan searched after it (its header less its preparation and search: a plan made in the
    world with the box), taken or not; to the first such plan that the gait takes; to the
    trajectory chunk after the status that says it taken (the first set-point of a plan
    avoiding it); and that last with the step's waits left out: when the first plan made with
    the box answers a request the gait made after the box was seen (the box did not block the
    plan under way: the planner did not replan on its own), the time from seen to that
    request; when the plan taken answers a request made after the first replan (which came too
    late in its step to be taken), the time from that replan to the request."""
    known, seen = set(), None
    out = {"seen→replan": [], "seen→plan taken": [], "seen→first set-point": [],
           "seen→first set-point, the step's waits left out": []}
    # [seen, the first plan made with the box, the last, taken, the last one's request,
    #  the first one's request]
    trial = None
    accepted = None
    requests = {}
    for ch, m in decoded(log):
        t = m["header"]["utime"] / 1e3
        if ch == "FOOTSTEP_PLAN_REQUEST":
            requests[m["request_id"]] = t
        elif ch == "OBSTACLES":
            ids = {o["id"] for o in m["obstacles"]}
            new = ids - known
            known |= ids
            if new and seen is not None and trial is None:
                trial = [t, None, None, None, None, None]
            seen = t
        elif ch == "FOOTSTEP_PLAN" and trial and trial[3] is None and m["status"] == 0:
            began = t - (m["prepare_time_us"] + m["search_time_us"]) / 1e3
            if began >= trial[0]:
                if trial[1] is None:
                    trial[1], trial[5] = t, requests.get(m["request_id"])
                # The plan the gait takes next (one answering a step already past is dropped).
                trial[2] = t
                trial[4] = requests.get(m["request_id"])
        elif ch == "GAIT_STATUS":
            a = m["accepted"]
            if trial and trial[2] is not None and trial[3] is None and accepted is not None \
                    and a > accepted:
                trial[3] = t
            accepted = a
        elif ch == "JOINT_TRAJECTORY_LEFT_LEG" and trial and trial[3] is not None:
            s0, first, taken_plan, _, asked, asked_first = trial
            out["seen→replan"].append(first - s0)
            out["seen→plan taken"].append(taken_plan - s0)
            out["seen→first set-point"].append(t - s0)
            wait = max(0.0, asked_first - s0) if asked_first is not None else 0.0
            if taken_plan != first and asked is not None:
                wait += max(0.0, asked - first)
            out["seen→first set-point, the step's waits left out"].append(t - s0 - wait)
            trial = None
    return out


def walk_logged(hosts, log, goal, timeout, sim_config=None):
    """Archie walked to `goal` (case 7, or the world of `sim_config`), recorded into `log` on
    the robot's side: on one host (hosts None: this namespace) or split over `hosts`."""
    def drive(stride):
        r = stride("walk", goal, "--timeout", timeout, timeout=timeout + 60)
        return r.stdout.strip().splitlines()[0] if r.stdout.strip() else r.stderr.strip()
    return session(hosts, log, drive, sim_config)


def session(hosts, log, drive, sim_config=None):
    """Archie's simulated robot launched (case 7, or the world of `sim_config`) on one host
    (hosts None: this namespace) or split over `hosts`, recorded into `log` on the robot's
    side while `drive(stride)` commands it (`stride(*args)` runs `stride ARGS` on the
    laptop); what it returns."""
    env = dict(os.environ, PATH=f"{REL}:{os.environ['PATH']}")
    logs = Path(tempfile.mkdtemp())
    if hosts is None:
        profile = ROOT / "config/launch/archie.toml"
        if sim_config:
            profile = edited_profile(profile, sim_config)
        url = profile_url(profile)
        on = {"robot": lambda *c: list(map(str, c)), "laptop": lambda *c: list(map(str, c))}
        deputies = [(["robot"], ["launch", profile, "--sim"])]
    else:
        profile = ROOT / "config/launch/archie-split.toml"
        if sim_config:
            profile = edited_profile(profile, sim_config)
        url = URL
        on = {h: (lambda h: lambda *c: hosts.on(h, *c))(h) for h in ["robot", "laptop"]}
        deputies = [(["robot"], ["launch", profile, "--host", "robot", "--sim"]),
                    (["laptop"], ["launch", profile, "--host", "laptop"])]
    procs = []
    for (host,), args in deputies:
        procs.append(subprocess.Popen(
            on[host](REL / "stride", "--lcm-url", url, "--log-level", "warn", *args,
                     "--log-dir", logs / host), env=env, stdout=subprocess.DEVNULL))
    loggers = [subprocess.Popen(on["robot"]("lcm-logger", "-q", "-f", "-c", STAGE_CHANNELS,
                                            f"--lcm-url={url}", log))]
    if hosts is not None:
        # The trajectories stay on the robot's own bus: logged there too.
        import tomllib
        local = tomllib.loads(profile.read_text())["local"]["robot"]["url"]
        loggers.append(subprocess.Popen(on["robot"](
            "lcm-logger", "-q", "-f", "-c", STAGE_CHANNELS, f"--lcm-url={local}",
            local_log(log))))
    def stride(*args, timeout=60):
        return subprocess.run(on["laptop"](REL / "stride", "--lcm-url", url, "--log-level",
                                           "warn", *args),
                              capture_output=True, text=True, env=env, timeout=timeout)

    def watch(channels):
        """`stride-spy echo` of `channels` on the laptop, left running: its JSON lines on
        stdout (one process for the whole run: no process started beside the robot's while
        it walks)."""
        return subprocess.Popen(on["laptop"](REL / "stride-spy", "echo", "--lcm-url", url,
                                             "--channel", channels),
                                stdout=subprocess.PIPE, text=True, env=env)
    stride.watch = watch
    try:
        # Every app up and the gait standing at its pose before the goal goes.
        time.sleep(25)
        summary = drive(stride)
    finally:
        for logger in loggers:
            logger.send_signal(2)
            logger.wait()
        for p in procs:
            p.send_signal(2)
        for p in procs:
            try:
                p.wait(timeout=60)
            except subprocess.TimeoutExpired:
                p.kill()
    return summary


def goal_trials(n):
    """`drive` for [`session`]: `n` goals sent to the standing robot, each walk stopped once
    under way and resumed (the robot stands again before the next)."""
    def drive(stride):
        for i in range(n):
            # Far along the corridor: every trial walks the same way.
            stride("goal", "30,0")
            time.sleep(1.0)
            stride("stop", "bench")
            time.sleep(2.5)
            stride("resume")
            time.sleep(0.5)
        return f"{n} goals sent"
    return drive


def box_trials(n, limit):
    """`drive` for [`session`]: the robot walked down the corridor where `n` boxes appear (a
    goal 40 m ahead, the next when it comes within 10 m: a plan reaches 50 m at most), and
    stopped once the last box has appeared and the next plan was walked (at most `limit` s),
    or when it has not come 0.5 m further along the corridor for a minute (boxed in by those
    that appeared: the boxes come every eighth touch-down, steps in place and sideways
    included, and may pile up around it). The simulated world's reports and obstacle lists
    are read from one stride-spy. Returns (boxes appeared, seconds, a line saying so)."""
    import threading

    def drive(stride):
        t0 = time.time()
        spy = stride.watch("SIM_REPORT|OBSTACLES")
        seen = {"boxes": 0, "x": 0.0, "at": time.time()}
        ahead = {"x": 0.0, "at": time.time()}

        def read():
            for line in spy.stdout:
                try:
                    m = json.loads(line)
                except ValueError:
                    continue
                if m["channel"] == "OBSTACLES":
                    k = len(m["message"]["obstacles"])
                    if k > seen["boxes"]:
                        seen["boxes"], seen["at"] = k, time.time()
                else:
                    feet = m["message"]["feet"]
                    seen["x"] = (feet[0][0] + feet[1][0]) / 2.0
        threading.Thread(target=read, daemon=True).start()
        goal = None
        stuck = False
        try:
            while seen["boxes"] < n and time.time() - t0 < limit:
                if goal is None or seen["x"] > goal - 10.0:
                    goal = seen["x"] + 40.0
                    stride("goal", f"{goal:.2f},0")
                time.sleep(1)
                if seen["x"] > ahead["x"] + 0.5:
                    ahead["x"], ahead["at"] = seen["x"], time.time()
                if time.time() - seen["at"] > 120 or time.time() - ahead["at"] > 60:
                    stuck = True
                    break
            # The last box's plan taken and under way.
            time.sleep(8)
            stride("stop", "bench")
        finally:
            spy.terminate()
            spy.wait()
        secs = time.time() - t0
        say = f"{seen['boxes']} of {n} boxes appeared in {secs:.0f} s"
        if stuck:
            say += f", the robot boxed in at x = {seen['x']:.1f} m"
        return seen["boxes"], secs, say
    return drive


def table(a, b, keys, bars):
    """Rows of a stage table, one host (`a`) against split (`b`); `bars` maps a stage to
    (bar, verdict of (one host, split, split adds at p99)). Returns rows and verdicts."""
    rows = ["| stage | one host: n, p50, p99 | split: n, p50, p99 | split adds, p99 | bar | verdict |",
            "|---|---|---|---|---|---|"]
    verdicts = []
    for k in keys:
        x, y = a[k], b[k]
        cell = lambda v: f"{len(v)}, {pct(v, 50):.1f} ms, {pct(v, 99):.1f} ms" if v else "0"
        add = pct(y, 99) - pct(x, 99) if x and y else float("nan")
        bar, ok = "-", None
        if k in bars and x and y:
            bar, judge = bars[k]
            ok = judge(x, y, add)
            verdicts.append(ok)
        elif k in bars:
            bar, ok = bars[k][0], False
            verdicts.append(ok)
        rows.append(f"| {k} | {cell(x)} | {cell(y)} | "
                    f"{'-' if add != add else f'{add:+.1f} ms'} | {bar} | "
                    f"{'-' if ok is None else ('meets' if ok else 'MISSES')} |")
    return rows, verdicts


SPLIT_ADDS = ("split adds < 5 ms", lambda x, y, add: add < 5)
FIRST_SET_POINT = ("p99 < 10 ms; split adds < 5 ms",
                   lambda x, y, add: pct(x, 99) < 10 and pct(y, 99) < 10 and add < 5)


def stages_bench(goal, timeout, goals, obstacles):
    """The stages, one host against split: goals sent to a standing robot; the plans of
    Archie's case 7 walked to its goal and of a corridor where boxes appear ahead; the boxes
    seen to a plan avoiding each; and each app's CPU while walking."""
    tmp = Path(tempfile.mkdtemp())
    runs = {}
    # Each corridor's plan stages and obstacle stages, one host and split (decoded once).
    boxed = {"one": ({}, {}), "split": ({}, {})}
    corridor = obstacle_world(0, 40.0)
    for where in ["one", "split"]:
        hosts = None if where == "one" else Hosts(False, where[0])
        try:
            say = "one host" if hosts is None else "split, the planner on the laptop"
            log(f"stages ({say}): {goals} goals sent to the standing robot")
            runs[where, "goals"] = session(hosts, tmp / f"{where}-goals.lcmlog",
                                           goal_trials(goals), corridor)
            log(f"stages ({say}): Archie's case 7 to {goal}")
            runs[where, "walk"] = walk_logged(hosts, tmp / f"{where}-walk.lcmlog", goal, timeout)
            log(f"  {runs[where, 'walk']}")
            # A corridor where the robot was boxed in is followed by a new one for the
            # trials still missing (three corridors at most).
            runs[where, "boxes"], trials = [], 0
            for part in range(3):
                left = obstacles - trials
                if left <= 0:
                    break
                # Long enough at the robot's longest strides; the walk stops after the last.
                length = round(0.25 * (4 + BOX_EVERY * left) + 20.0, 1)
                log(f"stages ({say}): {left} boxes appear on a {length} m corridor")
                limit = 120 + 2 * (4 + BOX_EVERY * left)
                boxes = tmp / f"{where}-boxes{part}.lcmlog"
                *_, said = session(hosts, boxes, box_trials(left, limit),
                                   obstacle_world(left, length))
                for whole, found in zip(boxed[where], [stages_of(boxes),
                                                       obstacle_stages_of(boxes)]):
                    for k, v in found.items():
                        whole.setdefault(k, []).extend(v)
                trials = len(boxed[where][1]["seen→first set-point"])
                runs[where, "boxes"].append(said)
                log(f"  {said}; {trials} trials so far")
        finally:
            if hosts is not None:
                hosts.close()
    stages = {}
    for where in ["one", "split"]:
        g = goal_stages_of(tmp / f"{where}-goals.lcmlog")
        w = stages_of(tmp / f"{where}-walk.lcmlog")
        o, b = boxed[where]
        stages[where] = {**g, **{k: w[k] + o.get(k, []) for k in w}, **b}
    keys = ["goal→first request", "goal→first set-point", "request→plan", "plan→taken",
            "plan→first set-point", "seen→replan", "seen→plan taken", "seen→first set-point",
            "seen→first set-point, the step's waits left out"]
    # The split's share of a box's stage is judged with the step's waits left out: they (up
    # to half a step, in about half the trials) are the gait's design, the same on one host
    # and split, and the p99 of 100 trials is the top of their spread (see BENCHMARKS.md).
    bars = {"goal→first set-point": SPLIT_ADDS, "request→plan": SPLIT_ADDS,
            "plan→first set-point": FIRST_SET_POINT,
            "seen→first set-point, the step's waits left out": SPLIT_ADDS}
    rows, verdicts = table(stages["one"], stages["split"], keys, bars)
    rows += ["", "The plans are those of both walks (case 7 and the corridor with boxes).", ""]
    for where, say in [("one", "One host"), ("split", "Split")]:
        rows.append(f"{say}: case 7: {runs[where, 'walk']}; the corridor: "
                    f"{'; then '.join(runs[where, 'boxes'])}")
        rows.append("")
    # CPU while walking (case 7), from the deputies' reports in the log.
    a, b = cpu_of(tmp / "one-walk.lcmlog"), cpu_of(tmp / "split-walk.lcmlog")
    rows += ["| app | CPU walking, one host | CPU walking, split |", "|---|---|---|"]
    for name in sorted(set(a) | set(b)):
        cell = lambda d: f"{d[name]:.2f} %" if name in d else "-"
        rows.append(f"| {name} | {cell(a)} | {cell(b)} |")
    return "\n".join(rows), all(verdicts)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--count", type=int, default=2000)
    ap.add_argument("--idle-secs", type=int, default=30)
    ap.add_argument("--goal", default="5,2")
    ap.add_argument("--timeout", type=int, default=150)
    ap.add_argument("--obstacles", type=int, default=100, help="boxes appearing (trials)")
    ap.add_argument("--goals", type=int, default=100, help="goals sent to a standing robot")
    ap.add_argument("parts", nargs="*", default=["zenoh", "idle", "stages"])
    a = ap.parse_args()
    out = []
    if "zenoh" in a.parts:
        t, ok = zenoh_bench(a.count)
        out.append("### The Zenoh hop against direct LCM\n\n" + t)
    if "idle" in a.parts:
        t, ok = idle_cpu(a.idle_secs)
        out.append("### Each app's CPU at idle (Archie's simulated robot, standing)\n\n" + t)
    if "stages" in a.parts:
        t, ok = stages_bench(a.goal, a.timeout, a.goals, a.obstacles)
        out.append("### Goal, plan and obstacle to the first set-point, one host against split"
                   "\n\n" + t)
    print("\n\n".join(out))


if __name__ == "__main__":
    main()
