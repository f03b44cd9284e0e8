//! Scene fields set from the command line by their dotted path (`solver.projection=…`):
//! `cargo xtask bench --set` (each value of a list in turn) and `cargo xtask validate --set`
//! (one value, on every BFEMP scene the suite runs).

use anyhow::{Context, Result, bail};
use serde_json::Value;

/// A scene field's dotted path (array elements by index) and the value it is set to.
pub type Setting = (String, Value);

/// `text` as a JSON value, or as a string if it is not JSON (`when_indefinite` needs no quotes).
pub fn value(text: &str) -> Value {
    serde_json::from_str(text).unwrap_or_else(|_| Value::String(text.to_string()))
}

/// `KEY=VALUE` split at the first `=`, both non-empty; `None` otherwise.
pub fn split(kv: &str) -> Option<(&str, &str)> {
    kv.split_once('=')
        .filter(|(k, v)| !k.is_empty() && !v.is_empty())
}

/// Set `key` (a dotted path) in `json` to `value`; objects on the way are created, an index
/// past an array's end or a path through a value that is no container is an error.
pub fn set(json: &mut Value, key: &str, value: &Value) -> Result<()> {
    let mut at = json;
    for part in key.split('.') {
        at = match at {
            Value::Object(m) => m
                .entry(part)
                .or_insert_with(|| Value::Object(Default::default())),
            Value::Array(a) => part
                .parse::<usize>()
                .ok()
                .and_then(|k| a.get_mut(k))
                .with_context(|| format!("--set {key}: no element `{part}`"))?,
            _ => bail!("--set {key}: `{part}` is inside a value, not an object or array"),
        };
    }
    *at = value.clone();
    Ok(())
}

/// `key=value key=value` (values as JSON), for labels and reports.
pub fn label(settings: &[Setting]) -> String {
    settings
        .iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Each setting as `key=value` (value as JSON), as `--set` takes it back.
pub fn labels(settings: &[Setting]) -> Vec<String> {
    settings
        .iter()
        .map(|s| label(std::slice::from_ref(s)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dotted_path_sets_nested_fields_and_says_where_it_cannot() {
        let mut json: Value =
            serde_json::from_str(r#"{"solver": {"tolerance": 1e-3}, "bodies": [{"a": 1}]}"#)
                .unwrap();
        set(&mut json, "solver.projection", &value("when_indefinite")).unwrap();
        set(&mut json, "bodies.0.a", &value("2")).unwrap();
        set(&mut json, "contact.friction", &value("0.5")).unwrap();
        assert_eq!(json["solver"]["projection"], "when_indefinite");
        assert_eq!(json["solver"]["tolerance"], 1e-3);
        assert_eq!(json["bodies"][0]["a"], 2);
        assert_eq!(json["contact"]["friction"], 0.5);
        let err = set(&mut json, "bodies.3.a", &value("1")).unwrap_err();
        assert!(err.to_string().contains("no element `3`"), "{err}");
        let err = set(&mut json, "solver.tolerance.x", &value("1")).unwrap_err();
        assert!(err.to_string().contains("`x` is inside a value"), "{err}");
        assert_eq!(split("a.b=1"), Some(("a.b", "1")));
        assert_eq!(split("a.b="), None);
        assert_eq!(split("=1"), None);
        assert_eq!(
            label(&[("a".into(), value("true")), ("b".into(), value("x"))]),
            "a=true b=\"x\""
        );
        assert_eq!(
            labels(&[("a".into(), value("1")), ("b".into(), value("[1,2]"))]),
            ["a=1", "b=[1,2]"]
        );
    }
}
