//! glTF 2.0 binary (`.glb`) writer: the JSON document is built with `gltf-json` (the
//! typed schema of the `gltf` crates), the binary chunk by hand.
//!
//! ```text
//! scene 0 ─ node "primfit" (translation = scene offset o)
//!             ├─ node "primitive_0_plane"  (translation = c₀ − o, mesh 0, extras)
//!             ├─ node "primitive_1_sphere" (translation = c₁ − o, mesh 1, extras)
//!             …
//! ```
//!
//! Each primitive's mesh has one triangle list: `POSITION` (`f32` × 3, relative to its
//! node: the primitive's bounding-box centre `cₖ`) and `u32` indices, and a material of
//! its palette colour (metallic 0, roughness 0.8, double-sided: squares and planes are
//! single sheets). Materials are shared by primitives of the same palette colour. No
//! normals are written: glTF viewers then shade flat, as the spec requires. The
//! offset `o` is the centre of all vertices rounded to `f32`, so the node translations
//! are exact and every stored coordinate is small. Node `extras` hold
//! `{"index": K, "type": "plane", "existence": 0.97}` (`existence` `null` when unknown).

use std::collections::BTreeMap;
use std::path::Path;

use gltf_json as json;
use json::validation::{Checked::Valid, USize64};
use nalgebra::{Point3, Vector3};

use super::Part;
use crate::io::write_atomic;
use crate::{Error, Result};

/// `glTF` magic, container version 2.
const MAGIC: &[u8; 4] = b"glTF";
/// Chunk types.
const CHUNK_JSON: &[u8; 4] = b"JSON";
const CHUNK_BIN: &[u8; 4] = b"BIN\0";

/// Writes `parts` to `path` (atomically) as a binary glTF.
pub(super) fn write_glb(path: &Path, parts: &[Part]) -> Result<()> {
    let (root, bin) = document(parts)?;
    let json_bytes = root
        .to_vec()
        .map_err(|e| Error::io(path, std::io::Error::other(e)))?;
    let glb = container(&json_bytes, &bin)
        .ok_or_else(|| Error::format(path, "too large for a .glb file (over 4 GiB)"))?;
    write_atomic(path, |w| w.write_all(&glb).map_err(|e| Error::io(path, e)))
}

/// The GLB container: header, JSON chunk (space-padded), BIN chunk (zero-padded, left
/// out when empty). `None` when it would exceed the format's `u32` length.
fn container(json_bytes: &[u8], bin: &[u8]) -> Option<Vec<u8>> {
    let pad = |n: usize| n.div_ceil(4) * 4;
    let json_len = pad(json_bytes.len());
    let bin_len = pad(bin.len());
    let total = 12 + 8 + json_len + if bin.is_empty() { 0 } else { 8 + bin_len };
    let total32 = u32::try_from(total).ok()?;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total32.to_le_bytes());
    out.extend_from_slice(&(json_len as u32).to_le_bytes());
    out.extend_from_slice(CHUNK_JSON);
    out.extend_from_slice(json_bytes);
    out.resize(20 + json_len, b' ');
    if !bin.is_empty() {
        out.extend_from_slice(&(bin_len as u32).to_le_bytes());
        out.extend_from_slice(CHUNK_BIN);
        out.extend_from_slice(bin);
        out.resize(total, 0);
    }
    Some(out)
}

/// The glTF document of `parts` and its binary buffer.
fn document(parts: &[Part]) -> Result<(json::Root, Vec<u8>)> {
    let mut root = json::Root {
        asset: json::Asset {
            generator: Some(format!("primfit {}", crate::VERSION)),
            ..json::Asset::default()
        },
        ..json::Root::default()
    };
    let mut bin = Vec::new();
    let offset = scene_offset(parts);
    let mut materials = BTreeMap::new();
    let mut children = Vec::with_capacity(parts.len());
    for part in parts {
        let mut node = json::Node {
            name: Some(part.name()),
            extras: Some(extras(part)?),
            ..json::Node::default()
        };
        if !part.mesh.faces.is_empty() {
            let centre = bounds_centre(&part.mesh.vertices);
            let material = *materials
                .entry(part.color())
                .or_insert_with(|| root.push(material(part.color())));
            let primitive = mesh_primitive(&mut root, &mut bin, part, &centre, material);
            node.mesh = Some(root.push(json::Mesh {
                name: Some(part.name()),
                primitives: vec![primitive],
                extensions: None,
                extras: None,
                weights: None,
            }));
            node.translation = Some((centre - offset).map(|c| c as f32).into());
        }
        children.push(root.push(node));
    }
    let top = root.push(json::Node {
        name: Some("primfit".into()),
        translation: Some(offset.coords.map(|c| c as f32).into()),
        children: (!children.is_empty()).then_some(children),
        ..json::Node::default()
    });
    let scene = root.push(json::Scene {
        name: Some("primfit".into()),
        nodes: vec![top],
        extensions: None,
        extras: None,
    });
    root.scene = Some(scene);
    if !bin.is_empty() {
        root.push(json::Buffer {
            byte_length: USize64::from(bin.len()),
            name: None,
            uri: None,
            extensions: None,
            extras: None,
        });
    }
    Ok((root, bin))
}

/// The node `extras` of a part.
fn extras(part: &Part) -> Result<Box<json::extras::RawValue>> {
    let value = serde_json::json!({
        "index": part.index,
        "type": part.kind,
        "existence": part.existence,
    });
    serde_json::value::to_raw_value(&value).map_err(|e| Error::invalid(e.to_string()))
}

/// A palette colour as an opaque PBR material (base colour in linear light).
fn material(rgb: [u8; 3]) -> json::Material {
    let linear = rgb.map(|c| srgb_to_linear(f32::from(c) / 255.0));
    json::Material {
        name: Some(format!("rgb {} {} {}", rgb[0], rgb[1], rgb[2])),
        double_sided: true,
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_factor: json::material::PbrBaseColorFactor([
                linear[0], linear[1], linear[2], 1.0,
            ]),
            metallic_factor: json::material::StrengthFactor(0.0),
            roughness_factor: json::material::StrengthFactor(0.8),
            ..Default::default()
        },
        ..Default::default()
    }
}

/// The sRGB transfer function inverted: a display value in [0, 1] → linear light.
fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Appends the part's positions (relative to `centre`) and indices to `bin` and returns
/// the glTF primitive reading them.
fn mesh_primitive(
    root: &mut json::Root,
    bin: &mut Vec<u8>,
    part: &Part,
    centre: &Point3<f64>,
    material: json::Index<json::Material>,
) -> json::mesh::Primitive {
    let local: Vec<[f32; 3]> = part
        .mesh
        .vertices
        .iter()
        .map(|v| (v - centre).map(|c| c as f32).into())
        .collect();
    let mut min = [f32::INFINITY; 3];
    let mut max = [f32::NEG_INFINITY; 3];
    for v in &local {
        for k in 0..3 {
            min[k] = min[k].min(v[k]);
            max[k] = max[k].max(v[k]);
        }
    }
    let positions: Vec<u8> = local
        .iter()
        .flatten()
        .flat_map(|c| c.to_le_bytes())
        .collect();
    let indices: Vec<u8> = part
        .mesh
        .faces
        .iter()
        .flatten()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let position = accessor(
        root,
        bin,
        &positions,
        local.len(),
        (
            json::accessor::Type::Vec3,
            json::accessor::ComponentType::F32,
        ),
        json::buffer::Target::ArrayBuffer,
        Some((min, max)),
    );
    let index = accessor(
        root,
        bin,
        &indices,
        3 * part.mesh.faces.len(),
        (
            json::accessor::Type::Scalar,
            json::accessor::ComponentType::U32,
        ),
        json::buffer::Target::ElementArrayBuffer,
        None,
    );
    json::mesh::Primitive {
        attributes: BTreeMap::from([(Valid(json::mesh::Semantic::Positions), position)]),
        extensions: None,
        extras: None,
        indices: Some(index),
        material: Some(material),
        mode: Valid(json::mesh::Mode::Triangles),
        targets: None,
    }
}

/// Appends `bytes` (a multiple of 4 long) to `bin` as a buffer view of its own and
/// returns an accessor of `count` elements of `layout` over it.
fn accessor(
    root: &mut json::Root,
    bin: &mut Vec<u8>,
    bytes: &[u8],
    count: usize,
    layout: (json::accessor::Type, json::accessor::ComponentType),
    target: json::buffer::Target,
    bounds: Option<([f32; 3], [f32; 3])>,
) -> json::Index<json::Accessor> {
    let view = root.push(json::buffer::View {
        buffer: json::Index::new(0),
        byte_length: USize64::from(bytes.len()),
        byte_offset: Some(USize64::from(bin.len())),
        byte_stride: None,
        name: None,
        target: Some(Valid(target)),
        extensions: None,
        extras: None,
    });
    bin.extend_from_slice(bytes);
    let (min, max) = bounds.map_or((None, None), |(lo, hi)| {
        (Some(serde_json::json!(lo)), Some(serde_json::json!(hi)))
    });
    root.push(json::Accessor {
        buffer_view: Some(view),
        byte_offset: None,
        count: USize64::from(count),
        component_type: Valid(json::accessor::GenericComponentType(layout.1)),
        extensions: None,
        extras: None,
        type_: Valid(layout.0),
        min,
        max,
        name: None,
        normalized: false,
        sparse: None,
    })
}

/// The centre of the bounding box of `points` (the origin when empty).
fn bounds_centre(points: &[Point3<f64>]) -> Point3<f64> {
    let Some(first) = points.first() else {
        return Point3::origin();
    };
    let (lo, hi) = points
        .iter()
        .fold((*first, *first), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
    nalgebra::center(&lo, &hi)
}

/// The scene offset: the centre of all vertices, rounded to `f32` so that it is stored
/// exactly.
fn scene_offset(parts: &[Part]) -> Point3<f64> {
    let all: Vec<Point3<f64>> = parts
        .iter()
        .flat_map(|p| p.mesh.vertices.iter().copied())
        .collect();
    let c = bounds_centre(&all);
    let rounded: Vector3<f64> = c.coords.map(|x| f64::from(x as f32));
    Point3::from(rounded)
}
