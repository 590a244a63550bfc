//! Hand annotations beside a map (`<map>.toml`): names and usable test areas of fragments.
//!
//! ```toml
//! [[fragment]]
//! id = "J5"                    # a fragment id from `video2track map inspect`
//! name = "north intersection"
//! test_area_m = [0.0, 350.0]   # optional: usable from/to along the fragment's first path, m
//! ```

use serde::Deserialize;

use crate::error::MapError;
use crate::library::TopologyLibrary;

/// The annotations of one map.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Annotations {
    /// Where they came from (for messages).
    #[serde(skip)]
    pub path: String,
    /// Per-fragment notes.
    #[serde(default)]
    pub fragment: Vec<FragmentNote>,
}

/// Notes on one fragment.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FragmentNote {
    /// Fragment id.
    pub id: String,
    /// A name operators know it by.
    pub name: Option<String>,
    /// Usable test area along the fragment's first path, m.
    pub test_area_m: Option<[f64; 2]>,
}

impl Annotations {
    /// Parses annotations TOML; `path` names the file in messages.
    pub fn parse(text: &str, path: &str) -> Result<Self, MapError> {
        let mut a: Self = toml::from_str(text)
            .map_err(|e| MapError::Annotations { path: path.to_owned(), message: e.to_string() })?;
        a.path = path.to_owned();
        Ok(a)
    }
}

pub(crate) fn apply(lib: &mut TopologyLibrary, notes: &Annotations) -> Result<(), MapError> {
    let err = |message: String| MapError::Annotations { path: notes.path.clone(), message };
    for (i, n) in notes.fragment.iter().enumerate() {
        let Some(f) = lib.fragments.iter_mut().find(|f| f.id == n.id) else {
            return Err(err(format!("fragment[{i}]: no fragment {:?} in this map", n.id)));
        };
        if let Some(name) = &n.name {
            if name.trim().is_empty() {
                return Err(err(format!("fragment[{i}].name must not be empty")));
            }
            f.name = Some(name.clone());
            f.description = format!("{name}: {}", f.description);
        }
        if let Some([from, to]) = n.test_area_m {
            let len = f.maneuvers.first().map_or(0.0, |m| crate::library::Polyline::new(&m.path).length());
            if !(from.is_finite() && to.is_finite() && 0.0 <= from && from < to && to <= len + 1e-6) {
                return Err(err(format!(
                    "fragment[{i}].test_area_m [{from}, {to}] must lie within [0, {len:.1}] and rise"
                )));
            }
            f.test_area_m = Some((from, to));
        }
    }
    Ok(())
}
