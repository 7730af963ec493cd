//! The lists whose entries declare parameters of their own: `sources`, `static_transforms`,
//! `exclusion_volumes` and `attached_objects`. An entry's name is the prefix of its parameters
//! (`front.topic` for the `<source>.topic` of source `front`), so a name may be used once
//! across the four lists; a given name is declared when the table has it, directly or under a
//! listed entry. The loader reads the lists here; the running node expands them
//! (`runtime`).

use std::collections::BTreeMap;

use yaml_rust2::Yaml;

use super::error::ConfigError;
use super::params::PARAMETERS;
use super::values::Values;

/// Each list and the prefix its entries' parameters are declared under.
pub(super) const LISTS: [(&str, &str); 4] = [
    ("sources", "<source>."),
    ("static_transforms", "<transform>."),
    ("exclusion_volumes", "<volume>."),
    ("attached_objects", "<object>."),
];

/// `later` over `values` (a later source: a `--params-file`, `-p`). Where it takes an entry out
/// of a list (`-p exclusion_volumes:=[]`), that entry's parameters given earlier are left out,
/// and logged, as the running node leaves them out; an entry still listed keeps them, and any
/// other undeclared name is still refused ([`Entries::read`]).
pub(super) fn apply_later(
    values: &mut BTreeMap<String, Yaml>,
    later: impl IntoIterator<Item = (String, Yaml)>,
) {
    let before = listed(values);
    values.extend(later);
    let after = listed(values);
    for ((list, template), (was, now)) in LISTS.iter().zip(before.iter().zip(&after)) {
        for gone in was.iter().filter(|e| !now.contains(e)) {
            let of_entry = |name: &str| {
                (name.strip_prefix(gone.as_str()))
                    .and_then(|r| r.strip_prefix('.'))
                    .is_some_and(|rest| {
                        let declared = format!("{template}{rest}");
                        PARAMETERS.iter().any(|d| d.name == declared)
                    })
            };
            let dropped: Vec<String> = values.keys().filter(|k| of_entry(k)).cloned().collect();
            for name in &dropped {
                values.remove(name);
            }
            if !dropped.is_empty() {
                log::info!(
                    "{gone} is no longer in {list}: its parameters ({}) are left out",
                    dropped.join(", ")
                );
            }
        }
    }
}

/// The entries of each list in `values` (an unreadable list as none: [`Entries::read`] says why).
fn listed(values: &BTreeMap<String, Yaml>) -> [Vec<String>; 4] {
    let v = Values {
        values: values.clone(),
    };
    LISTS.map(|(list, _)| v.strings(list).unwrap_or_default())
}

/// The names of one list entry's parameters: `("<name>.rest", "<template>.rest")`.
pub(super) fn names(entry: &str, template: &str, rest: &str) -> (String, String) {
    (format!("{entry}.{rest}"), format!("{template}.{rest}"))
}

/// The entries of the four lists, in the order of [`LISTS`].
pub(super) struct Entries {
    pub sources: Vec<String>,
    pub transforms: Vec<String>,
    pub volumes: Vec<String>,
    pub objects: Vec<String>,
}

impl Entries {
    /// Reads the lists, checks that no name is an entry of two, and that every given name is
    /// declared.
    pub fn read(v: &Values) -> Result<Self, ConfigError> {
        let [sources, transforms, volumes, objects] = LISTS.map(|(list, _)| v.strings(list));
        let entries = Self {
            sources: sources?,
            transforms: transforms?,
            volumes: volumes?,
            objects: objects?,
        };
        entries.check_unique()?;
        entries.check_declared(v)?;
        Ok(entries)
    }

    /// Each list with its declarations' prefix and its entries.
    fn lists(&self) -> [(&'static str, &'static str, &[String]); 4] {
        let [s, t, vo, o] = LISTS;
        [
            (s.0, s.1, &self.sources),
            (t.0, t.1, &self.transforms),
            (vo.0, vo.1, &self.volumes),
            (o.0, o.1, &self.objects),
        ]
    }

    fn check_unique(&self) -> Result<(), ConfigError> {
        let mut seen: BTreeMap<&str, &str> = BTreeMap::new();
        for (list, _, entries) in self.lists() {
            for e in entries {
                if let Some(other) = seen.insert(e.as_str(), list) {
                    return Err(Values::bad(
                        list,
                        format!("'{e}' is also an entry of {other}: names must differ"),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Every given name must be declared, directly or under a listed entry.
    fn check_declared(&self, v: &Values) -> Result<(), ConfigError> {
        let lists = self.lists();
        for name in v.values.keys() {
            let declared = PARAMETERS.iter().any(|d| {
                d.name == name
                    || lists.iter().any(|(_, prefix, entries)| {
                        d.name.strip_prefix(prefix).is_some_and(|rest| {
                            entries.iter().any(|e| name == &format!("{e}.{rest}"))
                        })
                    })
            });
            if !declared {
                return Err(ConfigError::Unknown(name.clone()));
            }
        }
        Ok(())
    }
}
