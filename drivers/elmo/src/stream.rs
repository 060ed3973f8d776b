//! Taking trajectories and playing them: where a trajectory starts and what it replaces,
//! the motion it asks for checked as the drives will play it (and its join with what they
//! do now), the stop that follows a chunk that ended in motion; then the rows sent as the
//! drives' tables have room and their time comes, every axis of a motion started together,
//! SYNCs, and what comes back.

use std::time::Instant;

use stride_canbus::{BusError, CanBus};
use stride_canopen::ds402;
use stride_canopen::elmo::{pt_frame, Command as Interp, PvtRow, Value};
use stride_canopen::sync;

use crate::config::Motion;
use crate::error::MasterError;
use crate::master::{controlword_rpdo, setpoint_rpdo, Event, Master, END_REPORT_WAIT};
use crate::plan::{self, Knot, Tag};
use crate::trajectory::{self, Start, Trajectory};

/// What an accepted trajectory became.
#[derive(Debug, Clone, PartialEq)]
pub struct Accepted {
    /// When its first row plays.
    pub start: Instant,
    /// When its last row plays (its stop, for a chunk that ends in motion, comes after).
    pub end: Instant,
    /// Rows of what was queued that it replaced.
    pub replaced: usize,
    /// The drives were stopped and were enabled again for it.
    pub rearmed: bool,
}

/// A knot that is not a row of the trajectory is named by the row next to it.
fn row_of(tag: Tag, rows: usize) -> usize {
    match tag {
        Tag::Row(r) => r,
        Tag::Join => 0,
        Tag::Stop => rows.saturating_sub(1),
    }
}

impl<B: CanBus> Master<B> {
    /// Checks a trajectory and queues it, replacing what was queued of its joints from its
    /// start on ([`Start`]); the drives' other joints go on as they were. Checked: its shape,
    /// its start (not passed, not before the motion the drives were already sent, within
    /// the queue's bound of `max_queue`), and the motion every drive will play, between rows
    /// too: the join with what the joint does at the start (the queued motion there, or
    /// where the joint stands: a first row at the start lies within the joint's tolerance
    /// of its measured position and velocity), the rows, and the stop after a last row in
    /// motion. Any position, speed or acceleration beyond a limit refuses the whole
    /// trajectory; nothing is clipped. When the drives were stopped (a quick stop, a fault),
    /// a valid trajectory enables them again first.
    pub fn load(&mut self, t: &Trajectory, now: Instant) -> Result<Accepted, MasterError> {
        // Resting, the states came less often: the full rate from now on.
        if self.resting() {
            self.next_sync = self.next_sync.min(now);
        }
        let r = self.try_load(t, now);
        match &r {
            Ok(a) => {
                self.counters.accepted += 1;
                self.counters.replaced_rows += a.replaced as u64;
            }
            Err(_) => self.counters.refused += 1,
        }
        r
    }

    fn try_load(&mut self, t: &Trajectory, now: Instant) -> Result<Accepted, MasterError> {
        let motion = self.cfg.motion;
        let interp = crate::master::curve_of(motion);
        let grid = motion.grid_us();
        let axes = &self.track.axes;
        let cols = trajectory::check_shape(
            t,
            |n| axes.iter().position(|a| a.cfg.name == n),
            |j| (axes[j].cfg.name.as_str(), axes[j].cfg.limits()),
            motion == Motion::Pvt,
        )?;
        let bad = MasterError::BadTrajectory;
        let now_us = self.us(now);
        let at = match t.start {
            Start::At(utime) => self.plan_us_of_wall(utime),
            _ => 0,
        };
        let rearm = self.stopped.is_some();
        let moving = |a: usize| {
            let ax = &self.track.axes[a];
            !rearm && (ax.playing || !ax.plan.is_empty())
        };
        // The first plan time every named joint may still change from.
        let earliest = cols
            .iter()
            .map(|&a| {
                let ax = &self.track.axes[a];
                if !moving(a) {
                    return now_us;
                }
                let drive_now = now_us - ax.lag + 1000;
                ax.plan.horizon().unwrap_or(now_us).max(drive_now)
            })
            .max()
            .unwrap_or(now_us);
        let s = match t.start {
            Start::Now => earliest,
            Start::At(_) => {
                let s = at;
                let bound = self.cfg.max_queue.as_micros() as i64;
                if s.saturating_sub(now_us) > bound {
                    return Err(bad(format!(
                        "start_utime is {:.1} s from now; the queue holds {:.1} s",
                        s.saturating_sub(now_us) as f64 * 1e-6,
                        self.cfg.max_queue.as_secs_f64()
                    )));
                }
                if s < now_us - 500 {
                    return Err(bad(format!(
                        "start_utime is {:.3} s in the past (0 starts at once)",
                        (now_us - s) as f64 * 1e-6
                    )));
                }
                if s < earliest - 500 {
                    return Err(bad(format!(
                        "start_utime is {:.1} ms from now, but the drives are sent the queued \
                         motion up to {:.1} ms from now (the lookahead): start later, or send 0",
                        (s - now_us) as f64 * 1e-3,
                        (earliest - now_us) as f64 * 1e-3
                    )));
                }
                s.max(earliest)
            }
            Start::Append => {
                let ends: Vec<(usize, i64)> = cols
                    .iter()
                    .filter(|&&a| moving(a))
                    .filter_map(|&a| self.track.axes[a].plan.chunk_end().map(|e| (a, e)))
                    .collect();
                let hi = ends.iter().map(|e| e.1).max();
                let lo = ends.iter().map(|e| e.1).min();
                match (lo, hi) {
                    (Some(lo), Some(hi)) if hi - lo > 1000 => {
                        let list: Vec<String> = ends
                            .iter()
                            .map(|(a, e)| {
                                format!(
                                    "{} {:.3} s",
                                    self.track.axes[*a].cfg.name,
                                    (e - now_us) as f64 * 1e-6
                                )
                            })
                            .collect();
                        return Err(bad(format!(
                            "the joints' queues end at different times ({}): an append needs one \
                             end; send a start time or replace",
                            list.join(", ")
                        )));
                    }
                    (_, Some(end)) if end < earliest => {
                        return Err(bad(format!(
                            "arrived {:.1} ms after the chunk it follows had to continue: the \
                             joints are stopping",
                            (earliest - end) as f64 * 1e-3
                        )));
                    }
                    (_, Some(end)) => end,
                    _ => earliest,
                }
            }
        };
        // On the table's grid: whole milliseconds, or the PT / IP period.
        let s = (s + grid - 1).div_euclid(grid) * grid;
        let us = t.micros();
        let last_us = *us.last().expect("checked: rows");
        let reach = s + last_us - now_us;
        if reach > self.cfg.max_queue.as_micros() as i64 {
            return Err(bad(format!(
                "it would end {:.1} s from now; the queue holds {:.1} s",
                reach as f64 * 1e-6,
                self.cfg.max_queue.as_secs_f64()
            )));
        }
        // Each joint's new plan, checked; none is changed before all pass.
        let mut plans = Vec::with_capacity(cols.len());
        let mut replaced = 0;
        for (c, &a) in cols.iter().enumerate() {
            let ax = &self.track.axes[a];
            let name = ax.cfg.name.clone();
            let limit = |row: usize, what: String| MasterError::Limit {
                row,
                joint: name.clone(),
                what,
            };
            let mut plan = ax.plan.clone();
            if rearm {
                plan.clear();
            }
            let p0 = t.positions[0][c];
            let v0 = t.velocity(0, c);
            let restart = !moving(a) || plan.ended();
            let mut new: Vec<Knot> = Vec::new();
            let join = match plan.end().copied() {
                // Continue what is queued: its state at the start, held past its end.
                Some(end) if !restart => {
                    if s > end.t {
                        new.extend(trajectory::hold(end.p, end.t, s, interp));
                    }
                    plan.state_at(s).unwrap_or((end.p, 0.0))
                }
                // A new motion from rest: where the last one ended, or where the joint stands.
                end => {
                    let (pm, vm) = match end.filter(|_| plan.ended()) {
                        Some(k) => (k.p, 0.0),
                        None => {
                            let period = self.cfg.sync_period.max(self.cfg.idle_sync_period);
                            let fresh = ax
                                .state
                                .updated
                                .is_some_and(|u| now.saturating_duration_since(u) <= period * 5);
                            if !fresh {
                                return Err(bad(format!(
                                    "{name}: no recent state from its drive to start from"
                                )));
                            }
                            (ax.state.position, ax.state.velocity)
                        }
                    };
                    let dv_max =
                        ax.cfg.max_acceleration * 1e-3 + ax.still_speed(self.cfg.sync_period);
                    if vm.abs() > dv_max {
                        return Err(bad(format!(
                            "{name} is moving ({vm:.3} rad/s): a motion starts from rest"
                        )));
                    }
                    if us[0] == 0 {
                        if (p0 - pm).abs() > ax.cfg.tolerance {
                            return Err(limit(
                                0,
                                format!(
                                    "starts at {p0:.4} rad, {:.4} rad from where the joint \
                                     stands ({pm:.4} rad): a first row at the start lies within \
                                     the joint's tolerance ({} rad)",
                                    (p0 - pm).abs(),
                                    ax.cfg.tolerance
                                ),
                            ));
                        }
                        if (v0 - vm).abs() > dv_max {
                            return Err(limit(
                                0,
                                format!(
                                    "starts at {v0:.3} rad/s while the joint moves at {vm:.3} \
                                     rad/s"
                                ),
                            ));
                        }
                    }
                    (pm, 0.0)
                }
            };
            let mut knots = trajectory::knots(t, c, s, join, interp)?;
            if restart {
                knots[0].first = true;
            }
            new.extend(knots);
            // A chunk that ends in motion is followed by its stop, until the next chunk comes;
            // less than half a count a second is rest (the drive's field rounds it to 0).
            let mut last = *new.last().expect("rows");
            if (last.v * ax.units.counts_per_rad()).abs() < 0.5 {
                last.v = 0.0;
                if let Some(k) = new.last_mut() {
                    k.v = 0.0;
                }
            }
            let tail = (last.v != 0.0).then_some(last.t);
            new.extend(plan::stop(
                last.t,
                last.p,
                last.v,
                ax.cfg.max_acceleration,
                interp,
                grid,
            ));
            // PT points go two to a frame: a motion's last point is repeated to fill it.
            if let Motion::Pt { .. } = motion {
                let kept = plan.pending().iter().filter(|k| k.t < s).count() as u64;
                let before = if restart { 0 } else { ax.written + kept };
                if (before + new.len() as u64) % 2 == 1 {
                    let end = *new.last().expect("rows");
                    new.push(Knot {
                        t: end.t + grid,
                        v: 0.0,
                        ..end
                    });
                }
            }
            let dropped = plan
                .splice(s, new, tail, &ax.bounds, s)
                .map_err(|v| limit(row_of(v.tag, t.times.len()), v.what))?;
            replaced += dropped;
            plans.push((a, plan));
        }
        if rearm {
            self.rearm()?;
        }
        for (a, plan) in plans {
            let ax = &mut self.track.axes[a];
            ax.plan = plan;
        }
        Ok(Accepted {
            start: self.instant(s),
            end: self.instant(s + last_us),
            replaced,
            rearmed: rearm,
        })
    }

    /// When the master next has something to do: a SYNC, or a motion to load or start.
    pub fn next_wake(&self) -> Instant {
        let lookahead = self.cfg.lookahead.as_micros() as i64;
        let mut wake = self.next_sync;
        for ax in &self.track.axes {
            // Playing, or waiting for the drive's report of its last motion's end (it comes
            // with the traffic, and the SYNC wakes the master meanwhile).
            if ax.playing || ax.ended_at.is_some() {
                continue;
            }
            if let Some(at) = ax.start_at {
                wake = wake.min(self.instant(at));
            } else if let Some(k) = ax.plan.pending().front() {
                wake = wake.min(self.instant(k.t - lookahead));
            }
        }
        wake
    }

    /// Sends what is due: rows while the drives' tables have room and their time is within
    /// the lookahead, the start of every axis whose motion begins now (all together), the
    /// SYNC; then takes in what arrived. Call it every cycle (and at [`Master::next_wake`]).
    pub fn pump(&mut self, now: Instant) -> Result<(), MasterError> {
        if self.stopped.is_none() {
            self.finish_motions(now);
            self.start_motions(now)?;
            self.send_rows(now)?;
        }
        self.pump_states(now)
    }

    /// The SYNC when due, the heartbeat, and what arrived.
    pub(crate) fn pump_states(&mut self, now: Instant) -> Result<(), MasterError> {
        // What arrived first: the states in it answer the SYNC already sent.
        self.take_in(now)?;
        let sync = now >= self.next_sync;
        // Resting, the SYNC goes less often (`idle_sync_period`).
        let period = if self.resting() {
            self.cfg.idle_sync_period
        } else {
            self.cfg.sync_period
        };
        // The heartbeat goes out with the SYNC (one batch where the bus is carried over LCM),
        // or on its own once it is late by a SYNC period.
        if sync || self.track.heartbeat.overdue(now, period) {
            let _ = self.track.heartbeat.poll(&mut self.bus, now);
        }
        if sync {
            self.next_sync = (self.next_sync + period).max(now);
            self.track.sync_period = period;
            match self
                .bus
                .send(&sync::encode(None), now + self.cfg.sdo_timeout)
            {
                Ok(()) => self.track.last_sync = Some(now),
                Err(BusError::TxQueueFull) => {}
                Err(e) => return Err(e.into()),
            }
            self.take_in(now)?;
        }
        self.track.watch_heartbeats(now);
        Ok(())
    }

    /// Every frame that has arrived.
    fn take_in(&mut self, now: Instant) -> Result<(), MasterError> {
        loop {
            match self.bus.try_recv() {
                Ok(Some(f)) => self.track.on_frame(&f, now, &mut self.bus),
                Ok(None) => return Ok(()),
                Err(e) => return Err(e.into()),
            }
        }
    }

    /// A motion whose last row has played is over: the axis is at rest, its table empty.
    fn finish_motions(&mut self, now: Instant) {
        let now_us = self.us(now);
        for ax in &mut self.track.axes {
            if ax.playing
                && ax.plan.ended()
                && ax
                    .plan
                    .last_sent()
                    .is_some_and(|k| now_us - ax.lag >= k.t + 5000)
            {
                ax.ended_at = Some(now_us);
                ax.end_motion();
            }
            // No report of the end came: the next motion goes ahead (a drive still playing
            // refuses its start, and says so).
            if ax
                .ended_at
                .is_some_and(|at| now_us - at > END_REPORT_WAIT.as_micros() as i64)
            {
                ax.ended_at = None;
                self.counters.unreported_ends += 1;
                self.track.events.push(Event::EndUnreported {
                    joint: ax.cfg.name.clone(),
                });
            }
        }
    }

    fn send_rows(&mut self, now: Instant) -> Result<(), MasterError> {
        let now_us = self.us(now);
        let lookahead = self.cfg.lookahead.as_micros() as i64;
        let motion = self.cfg.motion;
        let per_frame = motion.rows_per_frame();
        let mut stopping = Vec::new();
        // Rows go out round-robin, one frame per axis per pass, so that no axis starves
        // while the controller's queue is the bottleneck.
        'fill: loop {
            let mut sent_any = false;
            for a in 0..self.track.axes.len() {
                let ax = &mut self.track.axes[a];
                // The drive may still play the last motion: nothing new goes to its table.
                if ax.ended_at.is_some() {
                    continue;
                }
                // Keep a row spare: the drive's last row stays in its table until the next
                // motion moves its read pointer.
                if ax.queue.room() <= per_frame as u64 {
                    continue;
                }
                // Playing, or loaded to start (the start waits for two rows), on few rows:
                // the next rows go now, however far ahead they play.
                let starved = (ax.playing || ax.start_at.is_some()) && ax.queue.pending() < 3;
                let until = if starved {
                    i64::MAX
                } else {
                    now_us - ax.lag + lookahead
                };
                let ready = ax.plan.pending().len() >= per_frame
                    && ax.plan.pending()[per_frame - 1].t <= until
                    && !ax.plan.ended();
                if !ready {
                    continue;
                }
                let cob = setpoint_rpdo(motion).cob_id(ax.node);
                // The frame's knots, peeked: they leave the plan once the frame is sent.
                let Some((k, dt)) = ax.plan.next(until) else {
                    continue;
                };
                let second = if per_frame == 2 {
                    match ax.plan.pending().get(1) {
                        Some(n) if n.t <= until && !n.first => *n,
                        _ => continue,
                    }
                } else {
                    k
                };
                let units = ax.units;
                let fit = |e: crate::units::OutOfField| MasterError::Setup {
                    joint: ax.cfg.name.clone(),
                    node: ax.node.get(),
                    what: format!("a row at {:.4} rad: {e}", k.p),
                };
                let f = match motion {
                    Motion::Pvt => PvtRow {
                        position: units.position(k.p).map_err(fit)?,
                        velocity: units.velocity(k.v).map_err(fit)?,
                        time_ms: (dt / 1000).clamp(1, 255) as u8,
                    }
                    .frame(cob)
                    .map_err(|_| {
                        MasterError::BadTrajectory("a row does not fit its frame".into())
                    })?,
                    Motion::InterpolatedPosition { .. } => {
                        ds402::ip_setpoint_frame(cob, units.position(k.p).map_err(fit)?)
                    }
                    Motion::Pt { .. } => pt_frame(
                        cob,
                        units.position(k.p).map_err(fit)?,
                        units.position(second.p).map_err(fit)?,
                    ),
                };
                match self.bus.send(&f, now + self.cfg.sdo_timeout) {
                    Ok(()) => {
                        let ax = &mut self.track.axes[a];
                        let tail_before = ax.plan.tail().is_some();
                        if k.first {
                            ax.start_at = Some(k.t);
                            ax.written = 0;
                        }
                        for _ in 0..per_frame {
                            ax.plan.sent_front();
                            ax.queue.push();
                            ax.written += 1;
                        }
                        if tail_before && ax.plan.tail().is_none() {
                            stopping.push(ax.cfg.name.clone());
                        }
                        sent_any = true;
                    }
                    // The controller's queue is full: the rest waits for the next cycle.
                    Err(BusError::TxQueueFull) => break 'fill,
                    Err(e) => return Err(e.into()),
                }
            }
            if !sent_any {
                break;
            }
        }
        if !stopping.is_empty() {
            self.counters.stream_stops += 1;
            self.track
                .events
                .push(Event::StreamStopped { joints: stopping });
        }
        Ok(())
    }

    /// Every axis whose motion begins now gets its start: first every such axis's read
    /// pointer at its motion's first row, then the starts back to back, so the axes begin
    /// within a few frames' time of each other. What the controller's queue cannot take now
    /// goes first next cycle; an axis plays from when its start went out.
    fn start_motions(&mut self, now: Instant) -> Result<(), MasterError> {
        let now_us = self.us(now);
        let motion = self.cfg.motion;
        let starting: Vec<usize> = (0..self.track.axes.len())
            .filter(|&a| {
                let ax = &self.track.axes[a];
                // Loaded: two rows in the table, or all the motion has.
                let loaded = ax.queue.pending() >= 2 || ax.plan.is_empty() || ax.plan.ended();
                !ax.playing
                    && ax.ended_at.is_none()
                    && ax.start_at.is_some_and(|at| at <= now_us)
                    && loaded
            })
            .collect();
        let mut go = Vec::new();
        for a in starting {
            let ax = &mut self.track.axes[a];
            let node = ax.node;
            let at = ax.start_at.take().unwrap_or(now_us);
            // A motion of one row (a replacement cut it there) has nothing to play: a drive
            // refuses to begin a table of fewer than two rows, and reports no end.
            if ax.queue.pending() < 2 {
                ax.end_motion();
                continue;
            }
            match motion {
                Motion::Pvt | Motion::Pt { .. } => {
                    let name = if motion == Motion::Pvt { b"PV" } else { b"PT" };
                    let first = ax.queue.read_index() as i32;
                    if let Ok(f) = Interp::set(name, 0, Value::Int(first)).encode(node) {
                        self.starts.push_back((None, f));
                    }
                    if let Ok(f) = Interp::set(b"BG", 0, Value::Int(0)).encode(node) {
                        go.push((Some((a, at)), f));
                    }
                }
                // RPDO1 carries the controlword: enable operation + enable interpolation, on a
                // rising edge of bit 4 whatever the end of the last motion left it at.
                Motion::InterpolatedPosition { .. } => {
                    let cob = controlword_rpdo().cob_id(node);
                    let cw = |enable| {
                        ds402::controlword_frame(
                            cob,
                            ds402::ModeControl::InterpolatedPosition { enable }
                                .controlword(ds402::Command::EnableOperation, false),
                        )
                    };
                    self.starts.push_back((None, cw(false)));
                    go.push((Some((a, at)), cw(true)));
                }
            }
        }
        self.starts.extend(go);
        while let Some((axis, f)) = self.starts.front().cloned() {
            match self.bus.send(&f, now + self.cfg.sdo_timeout) {
                Ok(()) => {
                    self.starts.pop_front();
                    if let Some((a, at)) = axis {
                        let sent = self.us(self.bus.now()).max(at);
                        let ax = &mut self.track.axes[a];
                        ax.playing = true;
                        ax.lag = sent - at;
                    }
                }
                Err(BusError::TxQueueFull) => break,
                Err(e) => return Err(e.into()),
            }
        }
        Ok(())
    }
}
