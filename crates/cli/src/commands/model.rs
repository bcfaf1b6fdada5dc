//! Reading the model of `render` and `view`: the primitives (and existence) of a
//! result JSON.

use std::path::Path;

use anyhow::{Context, Result};
use primfit_core::Primitive;
use primfit_core::atlas::MeshShape;
use primfit_core::fit::FitResult;
use primfit_core::io;
use serde_json::Value;

/// The primitives of the result JSON at `path` and their existence when every entry
/// has one. A fit's result is read with [`FitResult::from_json`] (checked against the
/// whole schema); any other result (`synth --truth`, `register`) by its `primitives`
/// alone. Mesh sources are resolved relative to the result's folder.
pub fn read_model(path: &Path) -> Result<(Vec<Primitive>, Option<Vec<f64>>)> {
    let doc = read_document(path)?;
    let load = mesh_loader(path);
    if let Ok((result, _)) = FitResult::from_json(&doc, &load) {
        return Ok((result.primitives, Some(result.existence)));
    }
    let list = doc
        .get("primitives")
        .and_then(Value::as_array)
        .with_context(|| format!("{}: no \"primitives\" array", path.display()))?;
    let primitives = list
        .iter()
        .enumerate()
        .map(|(k, v)| {
            Primitive::from_json(v, &load)
                .with_context(|| format!("{}: primitive {k}", path.display()))
        })
        .collect::<Result<Vec<_>>>()?;
    let existence: Option<Vec<f64>> = list
        .iter()
        .map(|v| v.get("existence").and_then(Value::as_f64))
        .collect();
    Ok((primitives, existence))
}

/// The JSON document at `path`; the error names the file.
pub fn read_document(path: &Path) -> Result<Value> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{}: not valid JSON", path.display()))
}

/// Loads the mesh a primitive's `source` names: as given when absolute or present,
/// else relative to the folder of the result at `path`.
pub fn mesh_loader(path: &Path) -> impl Fn(&str) -> primfit_core::Result<MeshShape> + '_ {
    let base = path.parent().unwrap_or(Path::new("."));
    move |source: &str| {
        let p = Path::new(source);
        let p = if p.is_absolute() || p.exists() {
            p.to_path_buf()
        } else {
            base.join(p)
        };
        MeshShape::new(source, io::read_mesh(&p)?)
    }
}
