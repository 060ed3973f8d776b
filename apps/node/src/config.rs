//! TOML configuration files.

use std::path::Path;

use anyhow::Context;
use serde::de::DeserializeOwned;

/// Reads an app's configuration: the file's contents when a path is given, the defaults
/// otherwise. Errors name the file and the offending key or line.
pub fn load_config<T: DeserializeOwned + Default>(path: Option<&Path>) -> anyhow::Result<T> {
    let Some(path) = path else {
        return Ok(T::default());
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading configuration file {}", path.display()))?;
    toml::from_str(&text).with_context(|| format!("in configuration file {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Default, PartialEq, serde::Deserialize)]
    #[serde(deny_unknown_fields, default)]
    struct Cfg {
        rate_hz: f64,
        channel: String,
    }

    #[test]
    fn defaults_file_and_errors() {
        assert_eq!(load_config::<Cfg>(None).unwrap(), Cfg::default());
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.toml");
        std::fs::write(&p, "rate_hz = 5.0\nchannel = \"X\"\n").unwrap();
        let c: Cfg = load_config(Some(&p)).unwrap();
        assert_eq!(c.rate_hz, 5.0);
        std::fs::write(&p, "rate = 5.0\n").unwrap();
        let e = format!("{:#}", load_config::<Cfg>(Some(&p)).unwrap_err());
        assert!(e.contains("c.toml") && e.contains("rate"), "{e}");
        assert!(load_config::<Cfg>(Some(&dir.path().join("none.toml"))).is_err());
    }
}
