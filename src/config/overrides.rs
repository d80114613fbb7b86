//! Command-line overrides (`--set key=value`) applied to the raw TOML table.

use super::ConfigError;

const MODEL_KEYS: &[&str] = super::ModelConfig::KEYS;

/// Applies one `key=value` override to the raw TOML table; the value is parsed as TOML
/// (numbers, strings, arrays), falling back to a bare string.
pub(super) fn apply_override(table: &mut toml::Table, o: &str) -> Result<(), ConfigError> {
    let (key, value) = o.split_once('=').ok_or_else(|| {
        ConfigError::Parse(format!("override `{o}` is not of the form key=value"))
    })?;
    let key = key.trim();
    if o.chars().any(char::is_control) {
        return Err(ConfigError::Parse(format!(
            "override `{}` contains a newline or control character; give one key=value per override",
            o.escape_debug()
        )));
    }
    let (section, name) = match key.split_once('.') {
        Some((s, n)) => (s.to_string(), n.to_string()),
        None if MODEL_KEYS.contains(&key) => ("model".to_string(), key.to_string()),
        None => {
            return Err(ConfigError::Parse(format!(
                "override key `{key}` is neither `section.key` nor a model key ({MODEL_KEYS:?})"
            )));
        }
    };
    let parsed: toml::Value = toml::from_str::<toml::Table>(&format!("v = {}", value.trim()))
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(value.trim().to_string()));
    let entry = table
        .entry(section.clone())
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    match entry {
        toml::Value::Table(t) => {
            t.insert(name, parsed);
            Ok(())
        }
        _ => Err(ConfigError::Parse(format!("`{section}` is not a table"))),
    }
}
