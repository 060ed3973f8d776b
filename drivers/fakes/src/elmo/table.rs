//! The motion table of the fake drive: a ring of rows bounded by `MP[1]..MP[2]`, rows counted
//! as written and executed, and the pointers the drive publishes.

use stride_canopen::elmo::PvtRow;

/// Interpreter errors of the table commands.
pub(super) const ERR_OUT_OF_RANGE: u32 = 22;

/// The table and `MP[1..=6]`.
#[derive(Debug, Clone)]
pub(super) struct Table {
    rows: Vec<PvtRow>,
    /// `MP[0]` is unused; `MP[1..=6]` as the interpreter sets them.
    pub mp: [i32; 7],
    /// Rows written and executed since the table was last set up.
    pub written: u64,
    pub executed: u64,
    pvt_rows: u16,
}

impl Table {
    /// An empty table of `max(pvt_rows, pt_points)` rows, bounds at the PVT table.
    pub fn new(pvt_rows: u16, pt_points: u16) -> Table {
        Table {
            rows: vec![
                PvtRow {
                    position: 0,
                    velocity: 0,
                    time_ms: 1
                };
                pvt_rows.max(pt_points).max(1) as usize
            ],
            mp: [0, 1, pvt_rows as i32, 0, 1, 0, 1],
            written: 0,
            executed: 0,
            pvt_rows,
        }
    }

    /// Rows of the PVT table (`MP[2]` may not exceed it for PVT motion).
    pub fn pvt_rows(&self) -> u16 {
        self.pvt_rows
    }

    /// Rows of the table in use: `MP[1]..=MP[2]`.
    pub fn ring(&self) -> u64 {
        (self.mp[2] as i64 - self.mp[1] as i64 + 1).clamp(1, self.rows.len() as i64) as u64
    }

    /// Rows written, not yet executed.
    pub fn pending(&self) -> u64 {
        self.written - self.executed
    }

    /// The 1-based table index of the `count`-th row written.
    pub fn index_of(&self, count: u64) -> u16 {
        (self.mp[1].max(1) as u64 + count % self.ring()) as u16
    }

    /// The `count`-th row written.
    pub fn row_at(&self, count: u64) -> PvtRow {
        self.rows[(count % self.ring()) as usize]
    }

    /// Writes the next row; `Err` with the table index when the ring is full.
    pub fn push(&mut self, row: PvtRow) -> Result<(), u16> {
        if self.pending() >= self.ring() {
            return Err(self.index_of(self.written));
        }
        let slot = (self.written % self.ring()) as usize;
        self.rows[slot] = row;
        self.written += 1;
        self.mp[6] = self.index_of(self.written) as i32;
        Ok(())
    }

    /// The write and read pointers as table indices.
    pub fn pointers(&self) -> (u16, u16) {
        (self.index_of(self.written), self.index_of(self.executed))
    }

    /// `MP[6]=n`: the next row written lands at table index `n`; the table is emptied.
    pub fn set_write_pointer(&mut self, n: i32) -> Result<(), u32> {
        if !(self.mp[1]..=self.mp[2]).contains(&n) {
            return Err(ERR_OUT_OF_RANGE);
        }
        let ring = self.ring();
        let base = self.written + ring - self.written % ring;
        self.written = base + (n - self.mp[1]) as u64;
        self.executed = self.written;
        self.mp[6] = n;
        Ok(())
    }

    /// `PV=n` / `PT=n`: the read pointer moves to table index `n` (rows between it and the
    /// write pointer are what the next `BG` plays).
    pub fn set_read_pointer(&mut self, n: i32) -> Result<(), u32> {
        if !(self.mp[1]..=self.mp[2]).contains(&n) {
            return Err(ERR_OUT_OF_RANGE);
        }
        let ring = self.ring();
        let ws = self.written % ring;
        let target = (n - self.mp[1]) as u64;
        let mut back = (ws + ring - target) % ring;
        if back == 0 && self.pending() == ring {
            back = ring;
        }
        self.executed = self.written.checked_sub(back).ok_or(ERR_OUT_OF_RANGE)?;
        Ok(())
    }

    /// `MP[i]=v` for i in 1..=5, checked: the bounds lie in the table, `MP[3]` is 0..=3,
    /// `MP[4]` is 1..=65535 samples. New bounds empty the table.
    pub fn set_mp(&mut self, i: usize, v: i32) -> Result<(), u32> {
        let max = self.rows.len() as i32;
        let ok = match i {
            1 => (1..=self.mp[2]).contains(&v),
            2 => (self.mp[1]..=max).contains(&v),
            3 => (0..=3).contains(&v),
            4 => (1..=65535).contains(&v),
            5 => true,
            6 => return self.set_write_pointer(v),
            _ => false,
        };
        if !ok {
            return Err(ERR_OUT_OF_RANGE);
        }
        self.mp[i] = v;
        if i <= 2 {
            self.written = 0;
            self.executed = 0;
            self.mp[6] = self.index_of(0) as i32;
        }
        Ok(())
    }

    /// Back to power-on.
    pub fn reset(&mut self) {
        *self = Table::new(self.pvt_rows, self.rows.len() as u16);
    }
}
