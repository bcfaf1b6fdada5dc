//! Round trips of the mesh writers through independent readers (`gltf` for `.glb`,
//! `tobj` for `.obj`, our PLY reader for `.ply`), and their failures.

use std::fs;
use std::path::PathBuf;

use nalgebra::{Point3, UnitQuaternion, Vector3};

use super::*;
use crate::io::{palette_color, read_mesh};
use crate::{Pose, Shape};

/// A scratch directory, removed on drop.
struct Scratch(PathBuf);

impl Scratch {
    fn new(tag: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("primfit-export-{}-{tag}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).expect("create scratch dir");
        Scratch(dir)
    }
    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
    fn files(&self) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(&self.0)
            .expect("list")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

/// A square, a tilted cylinder and a sphere, the last far from the origin (as
/// georeferenced data are), with their existence.
fn scene(far: f64) -> (Vec<Primitive>, Vec<f64>) {
    let tilt = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.4);
    let prims = vec![
        Primitive::new(Shape::Square { side: 1.0 }, Pose::identity()),
        Primitive::new(
            Shape::Cylinder {
                length: 2.0,
                radius: 0.1,
            },
            Pose::new(tilt, Vector3::new(1.0, -2.0, 0.5)),
        ),
        Primitive::new(
            Shape::Sphere { diameter: 0.5 },
            Pose::new(UnitQuaternion::identity(), Vector3::new(far, far, 3.0)),
        ),
    ];
    (prims, vec![0.99, 0.75, 0.5])
}

/// Largest coordinate difference of two points.
fn gap(a: &Point3<f64>, b: &Point3<f64>) -> f64 {
    (a - b).amax()
}

#[test]
fn glb_reads_back_with_the_gltf_crate() {
    let dir = Scratch::new("glb");
    let far = 4.0e5; // f32 spacing there: 1/32 m
    let (prims, existence) = scene(far);
    let path = dir.path("fitted.glb");
    write_primitives_mesh(&path, &prims, Some(&existence), Encoding::default()).expect("write");
    let bytes = fs::read(&path).expect("read");
    // `from_slice` parses the container and validates the document against the schema.
    let gltf = gltf::Gltf::from_slice(&bytes).expect("valid glb");
    let blob = gltf.blob.as_deref().expect("a BIN chunk");
    let scene = gltf.default_scene().expect("a default scene");
    let top = scene.nodes().next().expect("a root node");
    let offset = Vector3::from(top.transform().decomposed().0.map(f64::from));
    let children: Vec<_> = top.children().collect();
    assert_eq!(children.len(), prims.len());
    for (k, (node, prim)) in children.iter().zip(&prims).enumerate() {
        let extras: serde_json::Value =
            serde_json::from_str(node.extras().as_ref().expect("extras").get()).expect("json");
        assert_eq!(extras["index"], k);
        assert_eq!(extras["type"], prim.shape.kind().name());
        assert_eq!(extras["existence"], existence[k]);
        let t = Vector3::from(node.transform().decomposed().0.map(f64::from)) + offset;
        let mesh = node.mesh().expect("a mesh");
        let primitive = mesh.primitives().next().expect("a primitive");
        let color = primitive
            .material()
            .pbr_metallic_roughness()
            .base_color_factor();
        let expected = palette_color(k).map(|c| srgb_to_linear(f32::from(c) / 255.0));
        assert!((0..3).all(|i| (color[i] - expected[i]).abs() < 1e-6));
        let reader = primitive.reader(|_| Some(blob));
        let positions: Vec<Point3<f64>> = reader
            .read_positions()
            .expect("positions")
            .map(|p| Point3::from(p.map(f64::from)) + t)
            .collect();
        let indices: Vec<u32> = reader.read_indices().expect("indices").into_u32().collect();
        let ours = prim.triangulate();
        assert_eq!(positions.len(), ours.vertices.len());
        assert_eq!(
            indices,
            ours.faces.iter().flatten().copied().collect::<Vec<_>>()
        );
        // Stored positions are f32 relative to the primitive's centre: within f32
        // rounding of the part (and of the f32 offset far from the origin).
        let tol = if k == 2 { far * 1e-7 } else { 1e-6 };
        for (a, b) in positions.iter().zip(&ours.vertices) {
            assert!(gap(a, b) < tol, "primitive {k}: {a} vs {b}");
        }
    }
}

/// The sRGB transfer function inverted (as glTF's linear base colours need).
fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

#[test]
fn obj_reads_back_with_tobj_exactly() {
    let dir = Scratch::new("obj");
    let (prims, existence) = scene(4.0e5);
    let path = dir.path("fitted.OBJ");
    write_primitives_mesh(&path, &prims, Some(&existence), Encoding::default()).expect("write");
    let options = tobj::LoadOptions {
        single_index: true,
        ..Default::default()
    };
    let (models, _) = tobj::load_obj(&path, &options).expect("tobj reads it");
    assert_eq!(models.len(), prims.len());
    for (k, (model, prim)) in models.iter().zip(&prims).enumerate() {
        assert_eq!(
            model.name,
            format!("primitive_{k}_{}", prim.shape.kind().name())
        );
        let ours = prim.triangulate();
        let m = &model.mesh;
        assert_eq!(m.positions.len(), 3 * ours.vertices.len());
        assert_eq!(m.indices.len(), 3 * ours.faces.len());
        let at = |i: u32| {
            let i = 3 * i as usize;
            Point3::new(m.positions[i], m.positions[i + 1], m.positions[i + 2])
        };
        // Every triangle corner is the same point, exactly (shortest round-trip text).
        for (f, corners) in ours.faces.iter().zip(m.indices.chunks(3)) {
            for (&v, &i) in f.iter().zip(corners) {
                assert_eq!(at(i), ours.vertices[v as usize]);
            }
        }
        let rgb = palette_color(k).map(|c| f64::from(c) / 255.0);
        assert!((0..3).all(|c| (m.vertex_color[c] - rgb[c]).abs() < 1e-4));
    }
    let text = fs::read_to_string(&path).expect("read");
    assert!(text.contains("# existence 0.75"));
}

#[test]
fn ply_is_the_fit_mesh_with_a_primitive_index_per_face() {
    let dir = Scratch::new("ply");
    let (prims, existence) = scene(10.0);
    let path = dir.path("fitted.ply");
    write_primitives_mesh(&path, &prims, Some(&existence), Encoding::Ascii).expect("write");
    let (mesh, _) = crate::fit::primitives_mesh(&prims);
    let back = read_mesh(&path).expect("read");
    assert_eq!(back.vertices, mesh.vertices);
    assert_eq!(back.faces, mesh.faces);
}

#[test]
fn an_empty_model_still_writes_valid_files() {
    let dir = Scratch::new("empty");
    for name in ["e.ply", "e.obj", "e.glb"] {
        write_primitives_mesh(&dir.path(name), &[], Some(&[]), Encoding::default()).expect("write");
    }
    let bytes = fs::read(dir.path("e.glb")).expect("read");
    let gltf = gltf::Gltf::from_slice(&bytes).expect("valid glb");
    assert_eq!(gltf.meshes().count(), 0);
    assert_eq!(gltf.nodes().count(), 1);
}

#[test]
fn bad_requests_fail_before_writing_anything() {
    let dir = Scratch::new("bad");
    let (prims, _) = scene(1.0);
    for name in ["fitted.stl", "fitted", "fitted.ply.tmp"] {
        let err = write_primitives_mesh(&dir.path(name), &prims, None, Encoding::default())
            .expect_err(name)
            .to_string();
        assert!(err.contains(name), "{err}");
        assert!(
            err.contains(".ply") && err.contains(".obj") && err.contains(".glb"),
            "{err}"
        );
    }
    let err = write_primitives_mesh(
        &dir.path("a.glb"),
        &prims,
        Some(&[0.5]),
        Encoding::default(),
    )
    .expect_err("mismatch");
    assert!(matches!(err, Error::Mismatch { .. }), "{err}");
    for name in ["a.obj", "a.glb"] {
        let target = dir.path("missing-folder").join(name);
        let err = write_primitives_mesh(&target, &prims, None, Encoding::default())
            .expect_err("no folder");
        assert!(err.to_string().contains("missing-folder"), "{err}");
    }
    assert!(dir.files().is_empty(), "{:?}", dir.files());
}

#[test]
fn an_existing_file_is_replaced_whole() {
    let dir = Scratch::new("replace");
    let (prims, _) = scene(1.0);
    let path = dir.path("fitted.glb");
    fs::write(&path, b"old").expect("write");
    write_primitives_mesh(&path, &prims, None, Encoding::default()).expect("write");
    let bytes = fs::read(&path).expect("read");
    assert_eq!(&bytes[..4], b"glTF");
    assert_eq!(dir.files(), ["fitted.glb"]);
    let gltf = gltf::Gltf::from_slice(&bytes).expect("valid glb");
    let node = gltf
        .nodes()
        .find(|n| n.mesh().is_some())
        .expect("a mesh node");
    let extras: serde_json::Value =
        serde_json::from_str(node.extras().as_ref().expect("extras").get()).expect("json");
    assert!(extras["existence"].is_null());
}
