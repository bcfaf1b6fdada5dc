//! Wavefront OBJ writer.
//!
//! Written by hand: OBJ is a line-oriented text format of a few record types (`o`, `v`,
//! `f`), and the crates that write it are either readers first (`tobj`) or unkept; a
//! dozen lines here avoid a dependency. Layout:
//!
//! ```text
//! # primfit VERSION: N primitives, one object each; v x y z r g b (colour in 0..1)
//! o primitive_0_plane
//! # existence 0.97
//! v 1.5 -0.25 0.75 0.1216 0.4667 0.7059
//! f 1 2 3
//! ```
//!
//! Colours follow each vertex's position (the common `v x y z r g b` extension read by
//! MeshLab, Blender, trimesh and tobj) instead of a `.mtl` material file, so that the
//! output stays one file written atomically. Coordinates use Rust's shortest
//! round-trip decimal form, so reading them back as `f64` is lossless. Face indices are
//! 1-based and global.

use std::path::Path;

use super::Part;
use crate::io::write_atomic;
use crate::{Error, Result};

/// Writes `parts` to `path` (atomically) as OBJ.
pub(super) fn write_obj(path: &Path, parts: &[Part]) -> Result<()> {
    write_atomic(path, |w| {
        let io = |e| Error::io(path, e);
        writeln!(
            w,
            "# primfit {}: {} primitives, one object each; v x y z r g b (colour in 0..1)",
            crate::VERSION,
            parts.len()
        )
        .map_err(io)?;
        let mut base = 1u64;
        for part in parts {
            writeln!(w, "o {}", part.name()).map_err(io)?;
            if let Some(e) = part.existence {
                writeln!(w, "# existence {e}").map_err(io)?;
            }
            let [r, g, b] = part.color().map(|c| f64::from(c) / 255.0);
            for v in &part.mesh.vertices {
                writeln!(w, "v {} {} {} {r:.4} {g:.4} {b:.4}", v.x, v.y, v.z).map_err(io)?;
            }
            for f in &part.mesh.faces {
                let [a, b, c] = f.map(|i| base + u64::from(i));
                writeln!(w, "f {a} {b} {c}").map_err(io)?;
            }
            base += part.mesh.vertices.len() as u64;
        }
        Ok(())
    })
}
