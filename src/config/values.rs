//! Typed access to a parameters file's values, flattened to dotted names, with the declared
//! defaults: each accessor checks the value and names the parameter in its error.

use std::collections::BTreeMap;

use yaml_rust2::Yaml;

use super::error::ConfigError;
use super::params::{scalar_yaml, PARAMETERS};
use crate::choice::Choice;

/// Flattens nested maps into dotted names.
pub(super) fn flatten(prefix: &str, y: &Yaml, out: &mut BTreeMap<String, Yaml>) {
    match y {
        Yaml::Hash(h) => {
            for (k, v) in h {
                let key = match k {
                    Yaml::String(s) => s.clone(),
                    other => format!("{other:?}"),
                };
                let name = if prefix.is_empty() {
                    key
                } else {
                    format!("{prefix}.{key}")
                };
                flatten(&name, v, out);
            }
        }
        _ => {
            out.insert(prefix.to_owned(), y.clone());
        }
    }
}

/// Typed access to the flattened values with the declared defaults.
pub(super) struct Values {
    pub(super) values: BTreeMap<String, Yaml>,
}

impl Values {
    pub(super) fn raw(&self, name: &str, template: &str) -> Yaml {
        if let Some(v) = self.values.get(name) {
            return v.clone();
        }
        let decl = PARAMETERS
            .iter()
            .find(|d| d.name == template)
            .expect("every read parameter is declared");
        scalar_yaml(decl.default)
    }
    pub(super) fn bad(name: &str, message: impl Into<String>) -> ConfigError {
        ConfigError::Invalid {
            name: name.to_owned(),
            message: message.into(),
        }
    }
    pub(super) fn f64_of(name: &str, y: &Yaml) -> Result<f64, ConfigError> {
        match y {
            Yaml::Real(_) => y.as_f64(),
            Yaml::Integer(i) => Some(*i as f64),
            _ => None,
        }
        .ok_or_else(|| Self::bad(name, format!("expected a number, got {}", show(y))))
    }
    pub(super) fn opt_f64(&self, name: &str, template: &str) -> Result<Option<f64>, ConfigError> {
        match self.raw(name, template) {
            Yaml::Null => Ok(None),
            y => Self::f64_of(name, &y).map(Some),
        }
    }
    /// A number ≥ 0 (finite unless `infinite_ok`).
    pub(super) fn distance(&self, name: &str, template: &str) -> Result<f64, ConfigError> {
        let v = self
            .opt_f64(name, template)?
            .ok_or_else(|| Self::bad(name, "a value is required"))?;
        if !(v >= 0.0 && v.is_finite()) {
            return Err(Self::bad(name, format!("must be finite and ≥ 0, got {v}")));
        }
        Ok(v)
    }
    /// A whole number ≥ 0 (a size in points or pixels).
    pub(super) fn whole(&self, name: &str) -> Result<usize, ConfigError> {
        let n = self.distance(name, name)?;
        if n.fract() != 0.0 || n > u64::MAX as f64 {
            return Err(Self::bad(name, "must be a whole number"));
        }
        Ok(n as usize)
    }
    /// A whole number ≥ 1.
    pub(super) fn count(&self, name: &str) -> Result<u32, ConfigError> {
        let n = self.distance(name, name)?;
        if n < 1.0 || n.fract() != 0.0 || n > u32::MAX as f64 {
            return Err(Self::bad(name, "must be a whole number ≥ 1"));
        }
        Ok(n as u32)
    }
    pub(super) fn bool(&self, name: &str, template: &str) -> Result<bool, ConfigError> {
        let y = self.raw(name, template);
        y.as_bool()
            .ok_or_else(|| Self::bad(name, format!("expected true or false, got {}", show(&y))))
    }
    pub(super) fn opt_string(
        &self,
        name: &str,
        template: &str,
    ) -> Result<Option<String>, ConfigError> {
        match self.raw(name, template) {
            Yaml::Null => Ok(None),
            Yaml::String(s) => Ok(Some(s)),
            y => Err(Self::bad(
                name,
                format!("expected a string, got {}", show(&y)),
            )),
        }
    }
    pub(super) fn string(&self, name: &str, template: &str) -> Result<String, ConfigError> {
        self.opt_string(name, template)?
            .ok_or_else(|| Self::bad(name, "a value is required"))
    }
    /// One of the values of `T`, by name; an error names the parameter and lists `T`'s names.
    /// Only a parameter declared with those values (`params::one_of`) is read so.
    pub(super) fn choice<T: Choice>(&self, name: &str, template: &str) -> Result<T, ConfigError> {
        let declared = PARAMETERS.iter().find(|d| d.name == template);
        if declared.and_then(|d| d.one_of).is_none() {
            return Err(Self::bad(name, "declared without the values it names"));
        }
        let text = self.string(name, template)?;
        T::parse(&text)
            .ok_or_else(|| Self::bad(name, format!("'{text}' (expected {})", T::names())))
    }
    pub(super) fn strings(&self, name: &str) -> Result<Vec<String>, ConfigError> {
        self.strings_of(name, name)
    }
    pub(super) fn strings_of(
        &self,
        name: &str,
        template: &str,
    ) -> Result<Vec<String>, ConfigError> {
        let y = self.raw(name, template);
        let list = y.as_vec().ok_or_else(|| {
            Self::bad(
                name,
                format!("expected a list of strings, got {}", show(&y)),
            )
        })?;
        list.iter()
            .map(|v| {
                v.as_str()
                    .map(str::to_owned)
                    .ok_or_else(|| Self::bad(name, format!("{} is not a string", show(v))))
            })
            .collect()
    }
    pub(super) fn numbers(&self, name: &str, template: &str) -> Result<Vec<f64>, ConfigError> {
        let y = self.raw(name, template);
        let list = y.as_vec().ok_or_else(|| {
            Self::bad(
                name,
                format!("expected a list of numbers, got {}", show(&y)),
            )
        })?;
        list.iter()
            .map(|v| {
                let x = Self::f64_of(name, v)?;
                x.is_finite()
                    .then_some(x)
                    .ok_or_else(|| Self::bad(name, "values must be finite"))
            })
            .collect()
    }
}

fn show(y: &Yaml) -> String {
    match y {
        Yaml::Real(s) | Yaml::String(s) => s.clone(),
        Yaml::Integer(i) => i.to_string(),
        Yaml::Boolean(b) => b.to_string(),
        Yaml::Null => "nothing".into(),
        Yaml::Array(_) => "a list".into(),
        Yaml::Hash(_) => "a map".into(),
        _ => format!("{y:?}"),
    }
}
