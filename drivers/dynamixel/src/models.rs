//! The control tables of the servo models, as data: one TOML file per model in `models/`
//! (addresses, sizes, access, EEPROM or RAM, defaults and ranges), with the units that turn
//! raw values into radians, rad/s, volts and so on. Item names are the same across models
//! where the meaning is (`goal_position`, `present_position`, `min_position_limit`…; on
//! Protocol 1.0 servos the position limits are the CW/CCW angle limits).

use std::collections::BTreeMap;
use std::sync::OnceLock;

use crate::Protocol;

/// Who may touch an item.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Deserialize)]
pub enum Access {
    /// Read only.
    #[serde(rename = "r")]
    Read,
    /// Read and write.
    #[serde(rename = "rw")]
    ReadWrite,
}

/// Where an item lives: EEPROM items keep their value through power cycles and, on most
/// models, can only be written with the torque off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Area {
    /// Non-volatile.
    Eeprom,
    /// Volatile.
    Ram,
}

/// How a velocity or load is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Encoding {
    /// Magnitude in bits 0..9, direction in bit 10 (set: clockwise, negative).
    #[serde(rename = "sign_bit_10")]
    SignBit10,
    /// Two's complement over the item's size.
    TwosComplement,
}

/// One control-table item.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Item {
    /// Address.
    pub address: u16,
    /// Size in bytes (1, 2 or 4).
    pub size: u8,
    /// Access.
    pub access: Access,
    /// EEPROM or RAM.
    pub area: Area,
    /// Factory value.
    pub default: i64,
    /// Lowest value the servo accepts.
    #[serde(default)]
    pub min: Option<i64>,
    /// Highest value the servo accepts.
    #[serde(default)]
    pub max: Option<i64>,
}

impl Item {
    /// The value as the item's little-endian bytes.
    pub fn encode(&self, value: i64) -> Vec<u8> {
        value.to_le_bytes()[..self.size as usize].to_vec()
    }

    /// The unsigned value of the item's bytes (`None` if `bytes` is short).
    pub fn decode(&self, bytes: &[u8]) -> Option<u32> {
        let b = bytes.get(..self.size as usize)?;
        let mut v = [0u8; 4];
        v[..b.len()].copy_from_slice(b);
        Some(u32::from_le_bytes(v))
    }

    /// True when `value` is inside the item's range.
    pub fn accepts(&self, value: i64) -> bool {
        let bits = self.size as u32 * 8;
        let fits = if self.min.is_some_and(|m| m < 0) {
            value >= -(1i64 << (bits - 1)) && value < (1i64 << (bits - 1))
        } else {
            value >= 0 && value < (1i64 << bits)
        };
        fits && self.min.is_none_or(|m| value >= m) && self.max.is_none_or(|m| value <= m)
    }
}

/// A servo model.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Model {
    /// Name, e.g. `AX-12A`.
    pub name: String,
    /// Model number, as the servo reports it (item `model_number`, and the 2.0 ping).
    pub number: u16,
    /// The protocol it speaks.
    pub protocol: Protocol,
    /// Position counts over `position_range_deg`.
    pub position_counts: u32,
    /// The angle the counts span.
    pub position_range_deg: f64,
    /// Velocity unit, rpm.
    pub velocity_unit_rpm: f64,
    /// Velocity encoding.
    pub velocity_encoding: Encoding,
    /// Load unit (percent of maximum torque), for models that report load.
    #[serde(default)]
    pub load_unit_percent: Option<f64>,
    /// Load encoding.
    #[serde(default)]
    pub load_encoding: Option<Encoding>,
    /// Current unit (mA), for models that report current.
    #[serde(default)]
    pub current_unit_ma: Option<f64>,
    /// Voltage unit, V.
    pub voltage_unit: f64,
    /// Fastest baud rate.
    pub max_baud: u32,
    /// Baud = `baud_divisor / (value + 1)` (Protocol 1.0 models), unless the table says.
    #[serde(default)]
    pub baud_divisor: Option<u32>,
    /// (value, baud) pairs of the baud rate item.
    #[serde(default)]
    pub baud_table: Vec<(u8, u32)>,
    /// The control table.
    pub items: BTreeMap<String, Item>,
}

const FILES: [&str; 6] = [
    include_str!("../models/ax-12a.toml"),
    include_str!("../models/mx-64.toml"),
    include_str!("../models/mx-106.toml"),
    include_str!("../models/xm430-w350.toml"),
    include_str!("../models/xh430-w350.toml"),
    include_str!("../models/xh430-v350.toml"),
];

/// Every model this crate knows.
pub fn all() -> &'static [Model] {
    static MODELS: OnceLock<Vec<Model>> = OnceLock::new();
    MODELS.get_or_init(|| {
        FILES
            .iter()
            .map(|text| toml::from_str(text).expect("the shipped model tables parse"))
            .collect()
    })
}

/// A model by name (case-insensitive, e.g. `ax-12a`).
pub fn by_name(name: &str) -> Option<&'static Model> {
    all().iter().find(|m| m.name.eq_ignore_ascii_case(name))
}

/// A model by the number a servo reports.
pub fn by_number(number: u16) -> Option<&'static Model> {
    all().iter().find(|m| m.number == number)
}

impl Model {
    /// An item by name.
    pub fn item(&self, name: &str) -> Option<&Item> {
        self.items.get(name)
    }

    /// The item at `address`, if one starts there.
    pub fn item_at(&self, address: u16) -> Option<(&str, &Item)> {
        self.items
            .iter()
            .find(|(_, i)| i.address == address)
            .map(|(n, i)| (n.as_str(), i))
    }

    /// Radians per position count.
    pub fn rad_per_count(&self) -> f64 {
        self.position_range_deg.to_radians() / self.position_counts as f64
    }

    /// The count at the middle of the range (the joint's zero before any offset).
    pub fn center(&self) -> i64 {
        self.position_counts as i64 / 2
    }

    /// The baud rate an item value selects.
    pub fn baud(&self, value: u8) -> Option<u32> {
        if let Some(&(_, b)) = self.baud_table.iter().find(|(v, _)| *v == value) {
            return Some(b);
        }
        self.baud_divisor.map(|d| d / (value as u32 + 1))
    }

    /// The item value that selects `baud`, if one does exactly.
    pub fn baud_value(&self, baud: u32) -> Option<u8> {
        (0..=255u8).find(|&v| self.baud(v) == Some(baud))
    }

    /// A raw velocity (or load) in signed units.
    pub fn signed(raw: u32, encoding: Encoding, size: u8) -> i64 {
        match encoding {
            Encoding::SignBit10 => {
                let m = (raw & 0x3ff) as i64;
                if raw & 0x400 != 0 {
                    -m
                } else {
                    m
                }
            }
            Encoding::TwosComplement => match size {
                1 => raw as u8 as i8 as i64,
                2 => raw as u16 as i16 as i64,
                _ => raw as i32 as i64,
            },
        }
    }

    /// Rad/s of a raw `present_velocity`.
    pub fn velocity_rad_s(&self, raw: u32) -> f64 {
        let size = self.item("present_velocity").map_or(4, |i| i.size);
        Self::signed(raw, self.velocity_encoding, size) as f64
            * self.velocity_unit_rpm
            * std::f64::consts::TAU
            / 60.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_tables_parse_and_agree() {
        assert_eq!(all().len(), FILES.len());
        for m in all() {
            let mn = m.item("model_number").expect("model_number");
            assert_eq!((mn.address, mn.default), (0, m.number as i64), "{}", m.name);
            for name in [
                "id",
                "baud_rate",
                "return_delay_time",
                "min_position_limit",
                "max_position_limit",
                "temperature_limit",
                "status_return_level",
                "torque_enable",
                "goal_position",
                "present_position",
                "present_velocity",
                "present_voltage",
                "present_temperature",
                "moving",
            ] {
                assert!(m.item(name).is_some(), "{} lacks {name}", m.name);
            }
            // Items do not overlap.
            let mut spans: Vec<(u16, u16)> = m
                .items
                .values()
                .map(|i| (i.address, i.address + i.size as u16))
                .collect();
            spans.sort();
            for w in spans.windows(2) {
                assert!(w[0].1 <= w[1].0, "{}: overlap at {:?}", m.name, w);
            }
            if m.protocol == Protocol::V1 {
                assert!(m.items.values().all(|i| i.address + i.size as u16 <= 256));
            }
        }
        let ax = by_name("ax-12a").unwrap();
        assert_eq!(ax.item("present_position").unwrap().address, 36);
        assert_eq!(
            (ax.baud(1), ax.baud(34), ax.baud_value(57_600)),
            (Some(1_000_000), Some(57_142), None)
        );
        let xm = by_number(1020).unwrap();
        assert_eq!(xm.name, "XM430-W350");
        assert_eq!(xm.item("goal_position").unwrap().address, 116);
        assert_eq!(
            (xm.baud(3), xm.baud_value(4_000_000)),
            (Some(1_000_000), Some(6))
        );
        assert_eq!(by_name("MX-64").unwrap().baud(252), Some(3_000_000));
    }

    #[test]
    fn units() {
        let ax = by_name("AX-12A").unwrap();
        assert_eq!(Model::signed(0x400 | 100, Encoding::SignBit10, 2), -100);
        assert_eq!(Model::signed(0xffff_fff6, Encoding::TwosComplement, 4), -10);
        assert!((ax.rad_per_count() - 300f64.to_radians() / 1024.0).abs() < 1e-12);
        let v = ax.velocity_rad_s(100);
        assert!((v - 100.0 * 0.111 * std::f64::consts::TAU / 60.0).abs() < 1e-9);
        let gp = ax.item("goal_position").unwrap();
        assert!(gp.accepts(1023) && !gp.accepts(1024) && !gp.accepts(-1));
        assert_eq!(gp.encode(512), [0x00, 0x02]);
        assert_eq!(gp.decode(&[0x00, 0x02]), Some(512));
    }
}
