//! The fake drive's network management: boot-up, NMT commands, the heartbeat it produces
//! (0x1017), and the heartbeats it consumes (0x1016) with what it does when one stops: the
//! error behaviour of 0x1029:1 for its NMT state and the abort connection option of 0x6007
//! for its motor.

use std::time::{Duration, Instant};

use stride_canopen::ds402::{self, AbortConnection, State as DriveState};
use stride_canopen::emcy::Emcy;
use stride_canopen::heartbeat::{self, ConsumerEntry};
use stride_canopen::nmt::{self, ErrorBehaviour, State as NmtState};

use super::FakeElmo;

impl FakeElmo {
    /// Power-on (or reset): the boot-up message, then pre-operational.
    pub(super) fn boot(&mut self, now: Instant) {
        self.booted = true;
        self.nmt = NmtState::BootUp;
        self.send(heartbeat::encode(self.cfg.node, NmtState::BootUp));
        self.nmt = NmtState::PreOperational;
        if self.drive == DriveState::NotReadyToSwitchOn {
            self.drive = ds402::next_state(DriveState::NotReadyToSwitchOn, 0, 0);
        }
        self.last_heartbeat = Some(now);
        self.heard.clear();
    }

    pub(super) fn on_nmt(&mut self, cmd: nmt::Command) {
        match cmd {
            nmt::Command::ResetNode => {
                let node = self.cfg.node;
                self.od = super::od::Od::new(node, self.cfg.following_error_window);
                self.sdo.reset();
                self.table.reset();
                self.motor = super::motion::Motor::new(self.cfg.ts_us);
                self.drive = DriveState::NotReadyToSwitchOn;
                self.prev_cw = 0;
                self.booted = false;
            }
            nmt::Command::ResetCommunication => {
                // The communication area goes back to its power-on values; the drive keeps
                // its application state.
                self.od
                    .reset_communication(self.cfg.node, self.cfg.following_error_window);
                self.sdo.reset();
                self.booted = false;
            }
            c => self.nmt = self.nmt.after(c),
        }
    }

    /// Sends the heartbeat when 0x1017 says it is due.
    pub(super) fn produce_heartbeat(&mut self, now: Instant) {
        let period = self.od.get_u(heartbeat::PRODUCER_TIME, 0);
        if period > 0
            && self
                .last_heartbeat
                .is_none_or(|t| now >= t + Duration::from_millis(period))
        {
            self.last_heartbeat = Some(now);
            let f = heartbeat::encode(self.cfg.node, self.nmt);
            self.send(f);
        }
    }

    /// The consumer entries of 0x1016 that watch a node.
    fn consumers(&self) -> Vec<ConsumerEntry> {
        let n = self.od.get_u(heartbeat::CONSUMER_TIME, 0) as u8;
        (1..=n)
            .map(|s| ConsumerEntry::from_u32(self.od.get_u(heartbeat::CONSUMER_TIME, s) as u32))
            .filter(|e| e.active())
            .collect()
    }

    /// A heartbeat (or boot-up) of node `from`: monitoring of it starts, or goes on.
    pub(super) fn on_heartbeat(&mut self, from: u8, now: Instant) {
        if self.consumers().iter().any(|e| e.node == from) {
            self.heard.insert(from, (now, false));
        }
    }

    /// A consumed heartbeat that stopped for longer than its consumer time is a heartbeat
    /// event: an EMCY (0x8130), the NMT state of 0x1029:1, and the reaction of 0x6007.
    pub(super) fn watch_heartbeats(&mut self, now: Instant) {
        // This process held up (a real drive's processor never is) longer than half a
        // consumer time: each watched node counts as heard no earlier than that, so its
        // silence is judged over time the drive watched, not over the fake's own absence.
        let consumers = self.consumers();
        if let Some(half) = consumers
            .iter()
            .map(|e| Duration::from_millis(e.time_ms as u64) / 2)
            .min()
        {
            let away = self
                .last_watch
                .is_some_and(|w| now.saturating_duration_since(w) > half);
            if away {
                let floor = now.checked_sub(half).unwrap_or(now);
                for (last, _) in self.heard.values_mut() {
                    *last = (*last).max(floor);
                }
            }
        }
        self.last_watch = Some(now);
        for e in consumers {
            let Some(&(last, reported)) = self.heard.get(&e.node) else {
                continue;
            };
            if reported
                || now.saturating_duration_since(last) <= Duration::from_millis(e.time_ms as u64)
            {
                continue;
            }
            self.heard.insert(e.node, (last, true));
            self.heartbeat_events += 1;
            let em = Emcy {
                node: self.cfg.node,
                code: Emcy::HEARTBEAT_ERROR,
                register: 0x11,
                manufacturer: [0; 5],
            };
            self.emcy(em);
            if self.nmt == NmtState::Operational {
                match ErrorBehaviour::from_code(self.od.get_u(nmt::ERROR_BEHAVIOUR, 1) as u8) {
                    Some(ErrorBehaviour::PreOperational) | None => {
                        self.nmt = NmtState::PreOperational
                    }
                    Some(ErrorBehaviour::Stopped) => self.nmt = NmtState::Stopped,
                    Some(ErrorBehaviour::NoChange) => {}
                }
            }
            let option = self.od.get_u(ds402::ABORT_CONNECTION_OPTION, 0) as u16 as i16;
            let before = self.drive;
            match AbortConnection::from_code(option) {
                Some(AbortConnection::QuickStop) if before == DriveState::OperationEnabled => {
                    self.drive = DriveState::QuickStopActive;
                    self.on_state_change(before);
                }
                Some(AbortConnection::DisableVoltage) if before != DriveState::Fault => {
                    self.drive = DriveState::SwitchOnDisabled;
                    self.on_state_change(before);
                }
                Some(AbortConnection::Fault) if before != DriveState::Fault => {
                    self.fault(Emcy::HEARTBEAT_ERROR);
                }
                _ => {}
            }
            self.update_status();
        }
    }
}
