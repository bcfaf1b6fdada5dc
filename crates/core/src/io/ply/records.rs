//! Per-element records that ply-rs-bw (binary) and our ascii reader fill through
//! [`PropertyAccess`], the writers read back, and the schemas that say which optional
//! attributes a file's `vertex` and `face` elements carry.

use std::path::Path;

use ply_rs_bw::ply::{ElementDef, PropertyAccess, PropertyAccessResult, PropertyType, ScalarType};

use crate::{Error, Result};

/// Property names of each optional vertex attribute (all must be present).
pub(super) const NORMAL: [&str; 3] = ["nx", "ny", "nz"];
/// Normal property names as PCL writes them.
pub(super) const PCL_NORMAL: [&str; 3] = ["normal_x", "normal_y", "normal_z"];
/// Colour property names (the usual ones).
pub(super) const RGB: [&str; 3] = ["red", "green", "blue"];
/// Colour property names (the `diffuse_` variant some tools write).
pub(super) const DIFFUSE_RGB: [&str; 3] = ["diffuse_red", "diffuse_green", "diffuse_blue"];
/// Sensor-origin property names.
pub(super) const SENSOR: [&str; 3] = ["sensor_x", "sensor_y", "sensor_z"];
/// Coordinate property names (required).
pub(super) const XYZ: [&str; 3] = ["x", "y", "z"];
/// The label property name.
pub(super) const LABEL: &str = "label";
/// The names a face's index list goes by.
pub(super) const FACE_LISTS: [&str; 2] = ["vertex_indices", "vertex_index"];
/// The per-face primitive index written by `write_mesh`.
pub(super) const PRIMITIVE: &str = "primitive";

/// A record that ignores every property: used to read past unwanted elements.
/// Zero-sized, so a `Vec<Skip>` never allocates.
pub(super) struct Skip;

impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
    }
}

/// One vertex with every attribute primfit knows (unset ones stay zero).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct VertexRecord {
    /// `x, y, z`.
    pub xyz: [f64; 3],
    /// `nx, ny, nz`.
    pub normal: [f64; 3],
    /// `red, green, blue` (or `diffuse_*`).
    pub rgb: [u8; 3],
    /// `label`.
    pub label: i32,
    /// `sensor_x, sensor_y, sensor_z`.
    pub sensor: [f64; 3],
}

/// Index of `name` in `names`.
fn slot(names: &[&str; 3], name: &str) -> Option<usize> {
    names.iter().position(|n| *n == name)
}

/// A colour channel given as a float in 0‥1, as a byte.
fn unit_to_byte(v: f64) -> u8 {
    // `as` saturates (and maps NaN to 0), which is what we want here.
    (v * 255.0).round() as u8
}

impl VertexRecord {
    /// The channel index (0, 1, 2) of a colour property name.
    fn color_slot(name: &str) -> Option<usize> {
        slot(&RGB, name).or_else(|| slot(&DIFFUSE_RGB, name))
    }

    /// Sets a property given as a floating-point value.
    fn set_real(&mut self, name: &str, v: f64) -> PropertyAccessResult {
        if let Some(i) = slot(&XYZ, name) {
            self.xyz[i] = v;
        } else if let Some(i) = slot(&NORMAL, name).or_else(|| slot(&PCL_NORMAL, name)) {
            self.normal[i] = v;
        } else if let Some(i) = slot(&SENSOR, name) {
            self.sensor[i] = v;
        } else if let Some(i) = Self::color_slot(name) {
            self.rgb[i] = unit_to_byte(v);
        } else {
            return PropertyAccessResult::Ignored;
        }
        PropertyAccessResult::Set
    }

    /// Sets a property given as an integer value.
    fn set_integer(&mut self, name: &str, v: i64) -> PropertyAccessResult {
        if name == LABEL {
            self.label = v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
        } else if let Some(i) = Self::color_slot(name) {
            self.rgb[i] = v.clamp(0, 255) as u8;
        } else {
            return self.set_real(name, v as f64);
        }
        PropertyAccessResult::Set
    }

    /// Reads a floating-point property back (for writing).
    fn get_real(&self, name: &str) -> Option<f64> {
        if let Some(i) = slot(&XYZ, name) {
            Some(self.xyz[i])
        } else if let Some(i) = slot(&NORMAL, name) {
            Some(self.normal[i])
        } else {
            slot(&SENSOR, name).map(|i| self.sensor[i])
        }
    }

    /// True when all three coordinates are finite.
    pub fn is_finite(&self) -> bool {
        self.xyz.iter().all(|c| c.is_finite())
    }
}

impl PropertyAccess for VertexRecord {
    fn new() -> Self {
        Self::default()
    }
    fn set_char(&mut self, name: &str, v: i8) -> PropertyAccessResult {
        self.set_integer(name, v.into())
    }
    fn set_uchar(&mut self, name: &str, v: u8) -> PropertyAccessResult {
        self.set_integer(name, v.into())
    }
    fn set_short(&mut self, name: &str, v: i16) -> PropertyAccessResult {
        self.set_integer(name, v.into())
    }
    fn set_ushort(&mut self, name: &str, v: u16) -> PropertyAccessResult {
        self.set_integer(name, v.into())
    }
    fn set_int(&mut self, name: &str, v: i32) -> PropertyAccessResult {
        self.set_integer(name, v.into())
    }
    fn set_uint(&mut self, name: &str, v: u32) -> PropertyAccessResult {
        self.set_integer(name, v.into())
    }
    fn set_float(&mut self, name: &str, v: f32) -> PropertyAccessResult {
        self.set_real(name, v.into())
    }
    fn set_double(&mut self, name: &str, v: f64) -> PropertyAccessResult {
        self.set_real(name, v)
    }
    fn get_double(&self, name: &str) -> Option<f64> {
        self.get_real(name)
    }
    fn get_uchar(&self, name: &str) -> Option<u8> {
        Self::color_slot(name).map(|i| self.rgb[i])
    }
    fn get_int(&self, name: &str) -> Option<i32> {
        (name == LABEL).then_some(self.label)
    }
}

/// One face read from a file: its vertex indices, widened to `i64`.
#[derive(Debug, Clone, Default)]
pub(super) struct FaceRecord {
    /// The `vertex_indices` (or `vertex_index`) list.
    pub indices: Vec<i64>,
}

impl FaceRecord {
    /// Stores an index list if `name` is one of [`FACE_LISTS`].
    fn set_list<T: Into<i64>>(&mut self, name: &str, v: Vec<T>) -> PropertyAccessResult {
        if !FACE_LISTS.contains(&name) {
            return PropertyAccessResult::Ignored;
        }
        self.indices = v.into_iter().map(Into::into).collect();
        PropertyAccessResult::Set
    }
}

impl PropertyAccess for FaceRecord {
    fn new() -> Self {
        Self::default()
    }
    fn set_list_char(&mut self, name: &str, v: Vec<i8>) -> PropertyAccessResult {
        self.set_list(name, v)
    }
    fn set_list_uchar(&mut self, name: &str, v: Vec<u8>) -> PropertyAccessResult {
        self.set_list(name, v)
    }
    fn set_list_short(&mut self, name: &str, v: Vec<i16>) -> PropertyAccessResult {
        self.set_list(name, v)
    }
    fn set_list_ushort(&mut self, name: &str, v: Vec<u16>) -> PropertyAccessResult {
        self.set_list(name, v)
    }
    fn set_list_int(&mut self, name: &str, v: Vec<i32>) -> PropertyAccessResult {
        self.set_list(name, v)
    }
    fn set_list_uint(&mut self, name: &str, v: Vec<u32>) -> PropertyAccessResult {
        self.set_list(name, v)
    }
}

/// One triangle to write, with its primitive index.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct TriangleOut {
    /// Vertex indices (checked to fit `int` before writing).
    pub indices: [i32; 3],
    /// The `primitive` property.
    pub primitive: i32,
}

impl PropertyAccess for TriangleOut {
    fn new() -> Self {
        Self::default()
    }
    fn get_list_int(&self, name: &str) -> Option<&[i32]> {
        FACE_LISTS.contains(&name).then_some(&self.indices[..])
    }
    fn get_int(&self, name: &str) -> Option<i32> {
        (name == PRIMITIVE).then_some(self.primitive)
    }
}

/// Which optional attributes a file's `vertex` element carries.
#[derive(Debug, Clone, Default)]
pub(super) struct VertexSchema {
    /// `nx, ny, nz` (or `normal_x, normal_y, normal_z`) all present as numbers.
    pub normals: bool,
    /// `red, green, blue` (or `diffuse_*`) all present as numbers.
    pub colors: bool,
    /// `label` present as an integer.
    pub labels: bool,
    /// `sensor_x, sensor_y, sensor_z` all present as numbers.
    pub sensors: bool,
    /// Properties that go nowhere, in header order.
    pub ignored: Vec<String>,
}

impl VertexSchema {
    /// Inspects `def`, failing when `x`, `y` or `z` is missing or is a list.
    pub fn of(def: &ElementDef, path: &Path) -> Result<Self> {
        for name in XYZ {
            match def.properties.get(name).map(|p| &p.data_type) {
                Some(PropertyType::Scalar(_)) => {}
                Some(PropertyType::List(..)) => {
                    let msg = format!("vertex property '{name}' is a list, expected a number");
                    return Err(Error::format(path, msg));
                }
                None => {
                    let msg = format!("the vertex element has no '{name}' property");
                    return Err(Error::format(path, msg));
                }
            }
        }
        let all = |names: &[&str; 3]| names.iter().all(|n| scalar_type(def, n).is_some());
        let mut schema = VertexSchema {
            normals: all(&NORMAL) || all(&PCL_NORMAL),
            colors: all(&RGB) || all(&DIFFUSE_RGB),
            labels: scalar_type(def, LABEL).is_some_and(is_integer),
            sensors: all(&SENSOR),
            ignored: Vec::new(),
        };
        schema.ignored = def
            .properties
            .keys()
            .filter(|n| !schema.uses(n))
            .cloned()
            .collect();
        Ok(schema)
    }

    /// True when property `name` feeds an attribute of this schema.
    fn uses(&self, name: &str) -> bool {
        XYZ.contains(&name)
            || (self.normals && (NORMAL.contains(&name) || PCL_NORMAL.contains(&name)))
            || (self.colors && (RGB.contains(&name) || DIFFUSE_RGB.contains(&name)))
            || (self.labels && name == LABEL)
            || (self.sensors && SENSOR.contains(&name))
    }
}

/// The type of scalar property `name` of `def`, if it is one.
fn scalar_type<'a>(def: &'a ElementDef, name: &str) -> Option<&'a ScalarType> {
    match def.properties.get(name).map(|p| &p.data_type) {
        Some(PropertyType::Scalar(t)) => Some(t),
        _ => None,
    }
}

/// True for the integer scalar types.
fn is_integer(t: &ScalarType) -> bool {
    !matches!(t, ScalarType::Float | ScalarType::Double)
}

/// Fails unless `def` (a `face` element) has an integer `vertex_indices` or
/// `vertex_index` list.
pub(super) fn check_face_schema(def: &ElementDef, path: &Path) -> Result<()> {
    let found = def.properties.values().any(|p| {
        FACE_LISTS.contains(&p.name.as_str())
            && matches!(&p.data_type, PropertyType::List(_, t) if is_integer(t))
    });
    if found {
        Ok(())
    } else {
        let msg = "the face element has no integer list 'vertex_indices' (or 'vertex_index')";
        Err(Error::format(path, msg))
    }
}
