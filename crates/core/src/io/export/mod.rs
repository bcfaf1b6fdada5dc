//! The fitted primitives as a triangle-mesh file, in the format the path's extension
//! names: [`write_primitives_mesh`].
//!
//! | extension (any case) | format | what each primitive becomes |
//! |---|---|---|
//! | `.ply` | PLY (binary little-endian, or ascii) | its faces, with a per-face `primitive` index and palette vertex colours ([`super::write_mesh`]) |
//! | `.obj` | Wavefront OBJ (text) | an object `o primitive_K_TYPE`, vertex colours after `x y z`, `# existence` comment |
//! | `.glb` | glTF 2.0 binary | a node with its own mesh and a palette material; node `extras` = `{"index", "type", "existence"}` |
//!
//! Every primitive `K` takes [`palette_color`]`(K)` in every format. Coordinates are
//! the scene's (the cloud's units): PLY and OBJ write them as `f64` text or doubles;
//! glTF stores `f32`, so its positions are kept small: each primitive's vertices are
//! relative to its node's translation (its bounding-box centre), under a root node
//! `primfit` that carries the scene offset (see `glb`), and georeferenced coordinates
//! near 10⁶ m survive to `f32` precision of the offset (about 6 cm there; exact below
//! 10³ m to 0.1 µm).
//!
//! Every writer goes through [`super::write_atomic`]: a failed write leaves no file and
//! never clobbers an existing one. An unknown extension is an [`Error::Format`] naming
//! the path and [`MESH_FORMATS`], raised before anything is written.

mod glb;
mod obj;

#[cfg(test)]
mod tests;

use std::path::Path;

use super::{Encoding, palette_color};
use crate::{Error, Primitive, Result, TriMesh, check};

/// The mesh formats [`write_primitives_mesh`] writes, as named in error messages.
pub const MESH_FORMATS: &str = "PLY (.ply), OBJ (.obj), glTF binary (.glb)";

/// A mesh file format of [`write_primitives_mesh`], chosen by extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    /// Stanford PLY (`.ply`).
    Ply,
    /// Wavefront OBJ (`.obj`).
    Obj,
    /// glTF 2.0 binary (`.glb`).
    Glb,
}

impl MeshFormat {
    /// The format named by `path`'s extension (any case); an [`Error::Format`] naming
    /// `path` and the accepted extensions otherwise.
    pub fn from_path(path: &Path) -> Result<MeshFormat> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("ply") => Ok(MeshFormat::Ply),
            Some("obj") => Ok(MeshFormat::Obj),
            Some("glb") => Ok(MeshFormat::Glb),
            other => {
                let found = other.map_or("no extension".to_string(), |e| {
                    format!("the extension '.{e}'")
                });
                Err(Error::format(
                    path,
                    format!(
                        "not a mesh format that is written: {found} (accepted: {MESH_FORMATS})"
                    ),
                ))
            }
        }
    }
}

/// One primitive's part of an exported mesh: what OBJ and glTF write per primitive.
#[derive(Debug, Clone)]
struct Part {
    /// Position in the primitive list (its palette colour and its name).
    index: usize,
    /// The type name (`"plane"`, `"cylinder"`, …).
    kind: &'static str,
    /// Its existence probability, when known.
    existence: Option<f64>,
    /// Its triangles in scene coordinates.
    mesh: TriMesh,
}

impl Part {
    /// `[r, g, b]` of this primitive ([`palette_color`] of its index).
    fn color(&self) -> [u8; 3] {
        palette_color(self.index)
    }
    /// `primitive_K_TYPE`: a name without spaces, as OBJ object names want.
    fn name(&self) -> String {
        format!("primitive_{}_{}", self.index, self.kind)
    }
}

/// The parts of `primitives`; `existence` must have one value each.
fn parts(primitives: &[Primitive], existence: Option<&[f64]>) -> Result<Vec<Part>> {
    if let Some(e) = existence {
        check::same_len("existence values", e.len(), "primitives", primitives.len())?;
    }
    Ok(primitives
        .iter()
        .enumerate()
        .map(|(index, p)| Part {
            index,
            kind: p.shape.kind().name(),
            existence: existence.map(|e| e[index]),
            mesh: p.triangulate(),
        })
        .collect())
}

/// Writes `primitives` (scene coordinates, the cloud's units) as one mesh file whose
/// format is chosen by `path`'s extension ([`MeshFormat::from_path`]; see the [module
/// docs](self)), atomically. `existence` (one probability per primitive, optional) goes
/// into OBJ comments and glTF node `extras`; `encoding` applies to PLY only.
///
/// ```
/// use primfit_core::io::{Encoding, write_primitives_mesh};
/// use primfit_core::{Pose, Primitive, Shape};
///
/// let prims = [Primitive::new(Shape::Square { side: 1.0 }, Pose::identity())];
/// let dir = std::env::temp_dir().join(format!("primfit-doc-export-{}", std::process::id()));
/// std::fs::create_dir_all(&dir)?;
/// for name in ["fitted.ply", "fitted.obj", "fitted.glb"] {
///     write_primitives_mesh(&dir.join(name), &prims, Some(&[0.9]), Encoding::default())?;
/// }
/// let err = write_primitives_mesh(&dir.join("fitted.stl"), &prims, None, Encoding::default());
/// assert!(err.unwrap_err().to_string().contains("fitted.stl"));
/// assert!(!dir.join("fitted.stl").exists());
/// std::fs::remove_dir_all(&dir)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn write_primitives_mesh(
    path: &Path,
    primitives: &[Primitive],
    existence: Option<&[f64]>,
    encoding: Encoding,
) -> Result<()> {
    let format = MeshFormat::from_path(path)?;
    let parts = parts(primitives, existence)?;
    match format {
        MeshFormat::Ply => {
            let mut mesh = TriMesh::default();
            let mut owner = Vec::new();
            for part in &parts {
                let range = mesh.append(&part.mesh);
                owner.extend(std::iter::repeat_n(part.index as i32, range.len()));
            }
            super::write_mesh(path, &mesh, Some(&owner), encoding)
        }
        MeshFormat::Obj => obj::write_obj(path, &parts),
        MeshFormat::Glb => glb::write_glb(path, &parts),
    }
}
