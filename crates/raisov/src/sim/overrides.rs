//! Scenario keys given in code on top of a scenario's TOML text ([`Simulation::from_file_with`]):
//! each override is merged into the parsed document before the typed parse, so a bad value is
//! reported as the same value written in the file: by its key's path, and by the line of the
//! merged text (the file's line where the override replaces a value in place and no key is
//! added before it; added keys go to the end of their table, or before the first table at
//! the top level, and move the lines after them).
//!
//! Merging: a table merges key by key into the table of the same name (created when absent);
//! any other value (a number, string, boolean, array, or an array of tables such as `fix`)
//! replaces the key's value.

use super::Simulation;
use crate::{Error, Result};
use std::path::Path;

/// `text` with `overrides` merged in (module docs); `path` names the text in errors.
pub fn merge(text: &str, overrides: &toml::Table, path: &Path) -> Result<String> {
    let mut doc: toml_edit::DocumentMut = text.parse().map_err(|e: toml_edit::TomlError| {
        let line = e
            .span()
            .map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1);
        Error::Scenario {
            path: path.to_path_buf(),
            line,
            msg: e.message().trim().to_string(),
        }
    })?;
    merge_table(doc.as_table_mut(), overrides, "", path)?;
    Ok(doc.to_string())
}

fn merge_table(
    t: &mut dyn toml_edit::TableLike,
    overrides: &toml::Table,
    prefix: &str,
    path: &Path,
) -> Result<()> {
    for (k, v) in overrides {
        let key = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        if let toml::Value::Table(sub) = v {
            if t.get(k).is_none() {
                t.insert(k, toml_edit::Item::Table(toml_edit::Table::new()));
            }
            let Some(inner) = t.get_mut(k).and_then(|i| i.as_table_like_mut()) else {
                return Err(Error::Scenario {
                    path: path.to_path_buf(),
                    line: None,
                    msg: format!(
                        "`{key}`: the override is a table of keys, the scenario's value is not"
                    ),
                });
            };
            merge_table(inner, sub, &key, path)?;
        } else {
            let value: toml_edit::Value = v.to_string().parse().map_err(|_| Error::Scenario {
                path: path.to_path_buf(),
                line: None,
                msg: format!("`{key}`: the override {v} is not a TOML value"),
            })?;
            match t.get_mut(k) {
                // In place: the key keeps its line and its decoration.
                Some(toml_edit::Item::Value(old)) => {
                    let decor = old.decor().clone();
                    *old = value;
                    *old.decor_mut() = decor;
                }
                Some(item) => *item = toml_edit::Item::Value(value),
                None => {
                    t.insert(k, toml_edit::Item::Value(value));
                }
            }
        }
    }
    Ok(())
}

impl Simulation {
    /// [`Simulation::from_file`] with scenario keys set in code: `overrides` is merged into
    /// the file's TOML document before it is parsed (tables key by key, other values
    /// replaced; [`overrides`](self)), so errors read as for the same keys in the file.
    ///
    /// ```
    /// # let dir = std::env::temp_dir().join(format!("raisov-doc-{}", std::process::id()));
    /// # std::fs::create_dir_all(&dir)?;
    /// # let path = dir.join("cube.toml");
    /// # std::fs::write(&path, "[mesh]\ngenerate = \"box\"\nsize = [0.04, 0.04, 0.04]\n\
    /// #   divisions = [2, 2, 2]\n[material]\nlaw = \"neo-hookean\"\nyoung = 5e3\n\
    /// #   poisson = 0.45\n[run]\nduration = 1.0\n")?;
    /// let overrides: toml::Table = toml::from_str("material = { young = 3e3 }")?;
    /// let sim = raisov::sim::Simulation::from_file_with(&path, &overrides)?;
    /// assert_eq!(sim.positions().len(), 27);
    /// // A bad value is reported as in the file: its key, and the line it replaces.
    /// let bad: toml::Table = toml::from_str("material = { young = -1.0 }")?;
    /// let err = raisov::sim::Simulation::from_file_with(&path, &bad).err().unwrap();
    /// assert!(err.to_string().contains("material.young"), "{err}");
    /// # std::fs::remove_dir_all(&dir)?;
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn from_file_with(path: impl AsRef<Path>, overrides: &toml::Table) -> Result<Simulation> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let text = merge(&text, overrides, path)?;
        Self::from_scenario(&crate::scenario::Scenario::from_toml(&text, path)?)
    }

    /// [`Simulation::from_toml`] with scenario keys set in code, as
    /// [`Simulation::from_file_with`].
    pub fn from_toml_with(
        text: &str,
        base_dir: impl AsRef<Path>,
        overrides: &toml::Table,
    ) -> Result<Simulation> {
        let path = base_dir.as_ref().join("scenario.toml");
        let text = merge(text, overrides, &path)?;
        Self::from_scenario(&crate::scenario::Scenario::from_toml(&text, &path)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_replace_values_in_place_and_add_tables() {
        let text = "# head\n[mesh]\ngenerate = \"box\" # the generator\n\n[material]\nyoung = 5e3\n\n[[fix]]\nplane = { point = [0, 0, 0], normal = [0, 0, 1] }\n";
        let o: toml::Table = toml::from_str(
            "gravity = [0.0, 0.0, -9.81]\nmaterial = { young = 3000.0, poisson = 0.4 }\ndamping = { alpha = 10 }\n[[fix]]\nbox = { min = [0, 0, 0], max = [1, 1, 0] }",
        )
        .unwrap();
        let merged = merge(text, &o, Path::new("s.toml")).unwrap();
        let back: toml::Table = toml::from_str(&merged).unwrap();
        assert_eq!(back["material"]["young"].as_float(), Some(3000.0));
        assert_eq!(back["material"]["poisson"].as_float(), Some(0.4));
        assert_eq!(back["damping"]["alpha"].as_integer(), Some(10));
        assert_eq!(back["gravity"].as_array().unwrap().len(), 3);
        assert_eq!(back["mesh"]["generate"].as_str(), Some("box"));
        let fix = back["fix"].as_array().unwrap();
        assert_eq!(fix.len(), 1);
        assert!(fix[0].get("box").is_some());
        // A replaced key stays on its line (line 6 of the file) when nothing is added before.
        let o: toml::Table = toml::from_str("material = { young = -1.0 }").unwrap();
        let merged = merge(text, &o, Path::new("s.toml")).unwrap();
        let line = merged.lines().position(|l| l.contains("young")).unwrap() + 1;
        assert_eq!(line, 6, "{merged}");
        // A table override over a value is an error naming the key.
        let o: toml::Table = toml::from_str("mesh = { generate = { x = 1 } }").unwrap();
        let e = merge(text, &o, Path::new("s.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("`mesh.generate`"), "{e}");
    }
}
