//! glTF 2.0 binary container (`.glb`): a 12-byte header, a JSON chunk and a BIN chunk, each padded to 4 bytes.
//!
//! The writer emits one mesh with one triangle primitive: `POSITION` (float VEC3, with the min/max the
//! specification requires), optional `NORMAL` (float VEC3) and `COLOR_0` (linear RGB as normalized
//! unsigned bytes, VEC3 with a 4-byte stride as the specification's vertex alignment asks: 4 bytes a
//! vertex instead of 12, colour steps of 1/255, finer than a colour ramp shows), and indices in face order
//! so face indices survive — `u16` below 65 535 vertices (the largest value of a type is not a valid
//! index), else `u32`; a matte, non-metallic material (optionally double-sided), and the node and mesh name
//! and the mesh's `extras` when given. glTF is metres and +y up, like skintight. Everything is core glTF
//! 2.0 (no extension a viewer would need to support).
//!
//! The reader takes every triangle primitive of every mesh; primitives that share a `POSITION` accessor share
//! vertices, so indices survive a round trip. Node transforms are not applied (meshes are read in their own
//! coordinates), and external buffers (`uri`) are not supported.

use std::collections::HashMap;

use serde::Deserialize;
use serde_json::json;

use super::{MeshFormat, MeshIoError, WriteParams};
use crate::math::Vec3;
use crate::mesh::TriMesh;

const FORMAT: MeshFormat = MeshFormat::Glb;
const MAGIC: u32 = 0x4654_6C67; // "glTF"
const CHUNK_JSON: u32 = 0x4E4F_534A; // "JSON"
const CHUNK_BIN: u32 = 0x004E_4942; // "BIN\0"
const FLOAT: u32 = 5126;
const UNSIGNED_BYTE: u32 = 5121;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const TRIANGLES: u32 = 4;

fn invalid(message: impl Into<String>) -> MeshIoError {
    MeshIoError::invalid(FORMAT, format!("glTF binary: {}", message.into()))
}

/// Writes a `.glb` file. Coordinates, normals and colours become `f32`. Fails for a mesh without faces
/// (glTF accessors cannot be empty).
pub fn write_glb(mesh: &TriMesh, params: &WriteParams<'_>) -> Result<Vec<u8>, MeshIoError> {
    if mesh.num_faces() == 0 {
        return Err(MeshIoError::Unwritable {
            format: FORMAT,
            message: "the mesh has no faces (glTF accessors cannot be empty)".into(),
        });
    }
    let nv = mesh.num_vertices();
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut attributes = serde_json::Map::new();

    // Positions, with min/max of the stored f32 values.
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    let start = bin.len();
    for p in &mesh.positions {
        for k in 0..3 {
            let x = p[k] as f32;
            lo[k] = lo[k].min(x);
            hi[k] = hi[k].max(x);
            bin.extend_from_slice(&x.to_le_bytes());
        }
    }
    let mut vec3_attribute = |bin: &Vec<u8>, start: usize, name: &str, extra: serde_json::Value| {
        views.push(
            json!({"buffer": 0, "byteOffset": start, "byteLength": bin.len() - start,
                          "target": ARRAY_BUFFER}),
        );
        let mut acc = json!({"bufferView": views.len() - 1, "componentType": FLOAT, "count": nv,
                             "type": "VEC3"});
        if let (Some(a), Some(e)) = (acc.as_object_mut(), extra.as_object()) {
            a.extend(e.clone());
        }
        accessors.push(acc);
        attributes.insert(name.into(), json!(accessors.len() - 1));
    };
    vec3_attribute(&bin, start, "POSITION", json!({"min": lo, "max": hi}));
    if let Some(normals) = params.normals {
        let start = bin.len();
        for n in normals {
            for x in n.iter() {
                bin.extend_from_slice(&(*x as f32).to_le_bytes());
            }
        }
        vec3_attribute(&bin, start, "NORMAL", json!({}));
    }
    if let Some(colors) = params.colors {
        let start = bin.len();
        for c in colors {
            for x in c {
                bin.push((x.clamp(0.0, 1.0) * 255.0).round() as u8);
            }
            bin.push(0);
        }
        views.push(
            json!({"buffer": 0, "byteOffset": start, "byteLength": bin.len() - start,
                   "byteStride": 4, "target": ARRAY_BUFFER}),
        );
        accessors.push(
            json!({"bufferView": views.len() - 1, "componentType": UNSIGNED_BYTE,
                              "normalized": true, "count": nv, "type": "VEC3"}),
        );
        attributes.insert("COLOR_0".into(), json!(accessors.len() - 1));
    }
    let start = bin.len();
    let short = nv < u16::MAX as usize;
    for face in &mesh.faces {
        for &v in face {
            if short {
                bin.extend_from_slice(&(v as u16).to_le_bytes());
            } else {
                bin.extend_from_slice(&(v as u32).to_le_bytes());
            }
        }
    }
    views.push(
        json!({"buffer": 0, "byteOffset": start, "byteLength": bin.len() - start,
                      "target": ELEMENT_ARRAY_BUFFER}),
    );
    accessors.push(json!({"bufferView": views.len() - 1,
                          "componentType": if short { UNSIGNED_SHORT } else { UNSIGNED_INT },
                          "count": 3 * mesh.num_faces(), "type": "SCALAR"}));
    let indices = accessors.len() - 1;

    // A matte dielectric (glTF's default material is fully metallic, which renders nearly black without an
    // environment map); vertex colours multiply the white base colour.
    let material = json!({
        "name": "skintight matte",
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0,
                                 "roughnessFactor": 0.8},
        "doubleSided": params.double_sided,
    });
    let mut mesh_json = json!({"primitives": [{"attributes": attributes, "indices": indices,
                                               "mode": TRIANGLES, "material": 0}]});
    let mut node = json!({"mesh": 0});
    if let Some(name) = params.name {
        mesh_json["name"] = json!(name);
        node["name"] = json!(name);
    }
    if let Some(extras) = params.extras {
        mesh_json["extras"] = extras.clone();
    }
    let doc = json!({
        "asset": {"version": "2.0", "generator": "skintight"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [node],
        "meshes": [mesh_json],
        "materials": [material],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}],
    });
    let mut json_bytes = serde_json::to_vec(&doc).map_err(|e| MeshIoError::Unwritable {
        format: FORMAT,
        message: e.to_string(),
    })?;
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json_bytes.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(&MAGIC.to_le_bytes());
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    out.extend_from_slice(&json_bytes);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
    out.extend_from_slice(&bin);
    Ok(out)
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct Document {
    #[serde(default)]
    meshes: Vec<GltfMesh>,
    #[serde(default)]
    accessors: Vec<Accessor>,
    #[serde(default)]
    buffer_views: Vec<BufferView>,
    #[serde(default)]
    buffers: Vec<Buffer>,
}

#[derive(Deserialize)]
struct GltfMesh {
    #[serde(default)]
    name: Option<String>,
    primitives: Vec<Primitive>,
}

#[derive(Deserialize)]
struct Primitive {
    attributes: HashMap<String, usize>,
    #[serde(default)]
    indices: Option<usize>,
    #[serde(default = "triangles")]
    mode: u32,
}

fn triangles() -> u32 {
    TRIANGLES
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct Accessor {
    #[serde(default)]
    buffer_view: Option<usize>,
    #[serde(default)]
    byte_offset: usize,
    component_type: u32,
    count: usize,
    #[serde(rename = "type")]
    kind: String,
    #[serde(default)]
    sparse: Option<serde_json::Value>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct BufferView {
    buffer: usize,
    #[serde(default)]
    byte_offset: usize,
    byte_length: usize,
    #[serde(default)]
    byte_stride: Option<usize>,
}

#[derive(Deserialize)]
struct Buffer {
    #[serde(default)]
    uri: Option<String>,
}

/// Reads a `.glb` file (see the module documentation for what is supported).
pub fn read_glb(bytes: &[u8]) -> Result<TriMesh, MeshIoError> {
    let u32_at = |o: usize| -> Option<u32> {
        bytes
            .get(o..o + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    if u32_at(0) != Some(MAGIC) {
        return Err(invalid("the file does not start with \"glTF\""));
    }
    let version = u32_at(4).unwrap_or(0);
    if version != 2 {
        return Err(invalid(format!("version {version}, only 2 is supported")));
    }
    let length = u32_at(8).ok_or_else(|| invalid("truncated header"))? as usize;
    if length > bytes.len() {
        return Err(invalid(format!(
            "truncated: header says {length} bytes but file has {}",
            bytes.len()
        )));
    }
    let bytes = &bytes[..length];
    let mut chunks: Vec<(u32, &[u8])> = Vec::new();
    let mut pos = 12;
    while pos + 8 <= bytes.len() {
        let len = u32_at(pos).unwrap_or(0) as usize;
        let kind = u32_at(pos + 4).unwrap_or(0);
        let data = bytes
            .get(pos + 8..pos + 8 + len)
            .ok_or_else(|| invalid(format!("chunk at byte {pos} runs past the end of the file")))?;
        chunks.push((kind, data));
        pos += 8 + len;
    }
    let json = match chunks.first() {
        Some(&(CHUNK_JSON, data)) => data,
        _ => return Err(invalid("the first chunk is not JSON")),
    };
    let bin: &[u8] = chunks
        .iter()
        .find(|c| c.0 == CHUNK_BIN)
        .map(|c| c.1)
        .unwrap_or(&[]);
    let doc: Document =
        serde_json::from_slice(json).map_err(|e| invalid(format!("bad JSON: {e}")))?;

    let mut positions: Vec<Vec3> = Vec::new();
    let mut faces: Vec<[usize; 3]> = Vec::new();
    let mut face_groups: Vec<u32> = Vec::new();
    let mut group_names: Vec<String> = Vec::new();
    // POSITION accessor → offset of its vertices in `positions`.
    let mut vertex_offset: HashMap<usize, usize> = HashMap::new();
    for (m, mesh) in doc.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let here = format!("mesh {m} primitive {p}");
            if prim.mode != TRIANGLES {
                return Err(invalid(format!(
                    "{here} has mode {}; only triangles (4) are supported",
                    prim.mode
                )));
            }
            let &pa = prim
                .attributes
                .get("POSITION")
                .ok_or_else(|| invalid(format!("{here} has no POSITION")))?;
            let count = doc
                .accessors
                .get(pa)
                .ok_or_else(|| invalid(format!("{here}: no accessor {pa}")))?
                .count;
            let offset = match vertex_offset.get(&pa) {
                Some(&o) => o,
                None => {
                    let o = positions.len();
                    let values = accessor_values(&doc, bin, pa, &[FLOAT], "VEC3")?;
                    positions.extend(values.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])));
                    vertex_offset.insert(pa, o);
                    o
                }
            };
            let local: Vec<usize> = match prim.indices {
                Some(ia) => accessor_values(
                    &doc,
                    bin,
                    ia,
                    &[UNSIGNED_BYTE, UNSIGNED_SHORT, UNSIGNED_INT],
                    "SCALAR",
                )?
                .into_iter()
                .map(|x| x as usize)
                .collect(),
                None => (0..count).collect(),
            };
            if !local.len().is_multiple_of(3) {
                return Err(invalid(format!(
                    "{here} has {} indices, not a multiple of 3",
                    local.len()
                )));
            }
            if let Some(&bad) = local.iter().find(|&&i| i >= count) {
                return Err(invalid(format!(
                    "{here} names vertex {bad}, but its POSITION has {count}"
                )));
            }
            let group = group_names.len() as u32;
            group_names.push(match &mesh.name {
                Some(n) if mesh.primitives.len() == 1 => n.clone(),
                Some(n) => format!("{n} {p}"),
                None => here,
            });
            for t in local.chunks_exact(3) {
                faces.push([t[0] + offset, t[1] + offset, t[2] + offset]);
                face_groups.push(group);
            }
        }
    }
    if group_names.len() <= 1 {
        face_groups.clear();
        group_names.clear();
    }
    Ok(TriMesh {
        positions,
        faces,
        face_groups,
        group_names,
    })
}

/// The values of accessor `a` as f64, checking component type, element type and bounds.
fn accessor_values(
    doc: &Document,
    bin: &[u8],
    a: usize,
    component_types: &[u32],
    kind: &str,
) -> Result<Vec<f64>, MeshIoError> {
    let acc = doc
        .accessors
        .get(a)
        .ok_or_else(|| invalid(format!("no accessor {a}")))?;
    if acc.sparse.is_some() {
        return Err(invalid(format!("accessor {a} is sparse (not supported)")));
    }
    if acc.kind != kind || !component_types.contains(&acc.component_type) {
        return Err(invalid(format!(
            "accessor {a} is {} of component type {}, expected {kind} of {component_types:?}",
            acc.kind, acc.component_type
        )));
    }
    let comps = if kind == "VEC3" { 3 } else { 1 };
    let size = match acc.component_type {
        UNSIGNED_BYTE => 1,
        UNSIGNED_SHORT => 2,
        _ => 4,
    };
    let Some(vi) = acc.buffer_view else {
        return Err(invalid(format!(
            "accessor {a} has no buffer view (all-zero accessors are not supported)"
        )));
    };
    let view = doc
        .buffer_views
        .get(vi)
        .ok_or_else(|| invalid(format!("accessor {a}: no buffer view {vi}")))?;
    match doc.buffers.get(view.buffer) {
        Some(Buffer { uri: None }) if view.buffer == 0 => {}
        _ => {
            return Err(invalid(format!(
                "buffer view {vi} refers to buffer {} outside the file (not supported)",
                view.buffer
            )));
        }
    }
    let stride = view.byte_stride.unwrap_or(size * comps);
    if stride < size * comps {
        return Err(invalid(format!(
            "buffer view {vi} has byteStride {stride}, less than one element ({} bytes)",
            size * comps
        )));
    }
    let view_end = view
        .byte_offset
        .saturating_add(view.byte_length)
        .min(bin.len());
    let begin = view.byte_offset.saturating_add(acc.byte_offset);
    let needed_end = if acc.count == 0 {
        begin
    } else {
        begin
            .saturating_add(stride.saturating_mul(acc.count - 1))
            .saturating_add(size * comps)
    };
    if needed_end > view_end {
        return Err(invalid(format!(
            "accessor {a} needs bytes up to {needed_end} but its buffer view ends at {view_end}"
        )));
    }
    let mut out = Vec::with_capacity(acc.count * comps);
    for k in 0..acc.count {
        for c in 0..comps {
            let o = begin + k * stride + c * size;
            let b = &bin[o..o + size];
            out.push(match acc.component_type {
                UNSIGNED_BYTE => b[0] as f64,
                UNSIGNED_SHORT => u16::from_le_bytes([b[0], b[1]]) as f64,
                UNSIGNED_INT => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                _ => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            });
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::octahedron;

    fn parse(bytes: &[u8]) -> (serde_json::Value, usize) {
        assert_eq!(&bytes[0..4], b"glTF");
        assert_eq!(u32::from_le_bytes(bytes[4..8].try_into().unwrap()), 2);
        assert_eq!(
            u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize,
            bytes.len()
        );
        let jlen = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        assert_eq!(&bytes[16..20], b"JSON");
        assert_eq!(jlen % 4, 0);
        let json: serde_json::Value = serde_json::from_slice(&bytes[20..20 + jlen]).unwrap();
        let blen = u32::from_le_bytes(bytes[20 + jlen..24 + jlen].try_into().unwrap()) as usize;
        assert_eq!(&bytes[24 + jlen..28 + jlen], b"BIN\0");
        assert_eq!(blen % 4, 0);
        assert_eq!(28 + jlen + blen, bytes.len());
        (json, blen)
    }

    #[test]
    fn written_glb_has_valid_layout_and_counts() {
        let m = octahedron();
        let normals: Vec<Vec3> = m.positions.iter().map(|p| p.normalize()).collect();
        let colors: Vec<[f32; 3]> = (0..6).map(|i| [i as f32 / 5.0, 0.25, 1.0]).collect();
        let params = WriteParams {
            normals: Some(&normals),
            colors: Some(&colors),
            ..Default::default()
        };
        let bytes = write_glb(&m, &params).unwrap();
        let (json, blen) = parse(&bytes);
        assert_eq!(json["asset"]["version"], "2.0");
        assert_eq!(
            json["buffers"][0]["byteLength"].as_u64().unwrap() as usize,
            blen
        );
        let prim = &json["meshes"][0]["primitives"][0];
        let acc =
            |name: &str| &json["accessors"][prim["attributes"][name].as_u64().unwrap() as usize];
        assert_eq!(acc("POSITION")["count"], 6);
        assert_eq!(acc("NORMAL")["count"], 6);
        assert_eq!(acc("COLOR_0")["count"], 6);
        let s = 0.123456789012345_f64 as f32 as f64;
        assert_eq!(acc("POSITION")["max"][0].as_f64().unwrap(), s);
        assert_eq!(acc("POSITION")["min"][1].as_f64().unwrap(), -s);
        let idx = &json["accessors"][prim["indices"].as_u64().unwrap() as usize];
        assert_eq!(idx["count"], 24);
        assert_eq!(idx["componentType"], UNSIGNED_SHORT);
        // Colours: normalized bytes with a 4-byte stride, each within half a step of the given value.
        let color = acc("COLOR_0");
        assert_eq!(color["componentType"], UNSIGNED_BYTE);
        assert_eq!(color["normalized"], true);
        let view = &json["bufferViews"][color["bufferView"].as_u64().unwrap() as usize];
        assert_eq!(view["byteStride"], 4);
        let (jlen, at) = (
            u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize,
            view["byteOffset"].as_u64().unwrap() as usize,
        );
        for (v, c) in colors.iter().enumerate() {
            for k in 0..3 {
                let stored = bytes[28 + jlen + at + 4 * v + k] as f32 / 255.0;
                assert!((stored - c[k]).abs() <= 0.5 / 255.0 + 1e-7, "{v} {k}");
            }
        }
        for v in json["bufferViews"].as_array().unwrap() {
            assert_eq!(v["byteOffset"].as_u64().unwrap() % 4, 0);
        }
        let back = read_glb(&bytes).unwrap();
        assert_eq!(back.faces, m.faces);
        assert_eq!(back.num_vertices(), 6);
        // From 65 535 vertices on, u32 indices (65 535 itself is no valid u16 index).
        let mut big = m.clone();
        big.positions
            .resize(u16::MAX as usize, Vec3::new(0.0, 0.0, 1.0));
        big.faces.push([0, 1, u16::MAX as usize - 1]);
        let bytes = write_glb(&big, &WriteParams::default()).unwrap();
        let (json, _) = parse(&bytes);
        let prim = &json["meshes"][0]["primitives"][0];
        let idx = &json["accessors"][prim["indices"].as_u64().unwrap() as usize];
        assert_eq!(idx["componentType"], UNSIGNED_INT);
        assert_eq!(read_glb(&bytes).unwrap().faces, big.faces);
    }

    #[test]
    fn primitives_sharing_positions_share_vertices() {
        // Split the octahedron's faces into two primitives over one POSITION accessor by editing the JSON.
        let m = octahedron();
        let bytes = write_glb(&m, &WriteParams::default()).unwrap();
        let (mut json, _) = parse(&bytes);
        let jlen = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        let bin_chunk = bytes[20 + jlen..].to_vec();
        let mut acc2 = json["accessors"][1].clone();
        acc2["count"] = json!(12);
        // Twelve indices of the stored size (u16 for six vertices).
        acc2["byteOffset"] = json!(12 * 2);
        json["accessors"][1]["count"] = json!(12);
        json["accessors"].as_array_mut().unwrap().push(acc2);
        let mut p2 = json["meshes"][0]["primitives"][0].clone();
        p2["indices"] = json!(2);
        json["meshes"][0]["primitives"]
            .as_array_mut()
            .unwrap()
            .push(p2);
        let mut js = serde_json::to_vec(&json).unwrap();
        while js.len() % 4 != 0 {
            js.push(b' ');
        }
        let mut out = Vec::new();
        out.extend(MAGIC.to_le_bytes());
        out.extend(2u32.to_le_bytes());
        out.extend(((12 + 8 + js.len() + bin_chunk.len()) as u32).to_le_bytes());
        out.extend((js.len() as u32).to_le_bytes());
        out.extend(CHUNK_JSON.to_le_bytes());
        out.extend(&js);
        out.extend(&bin_chunk);
        let back = read_glb(&out).unwrap();
        assert_eq!(back.faces, m.faces);
        assert_eq!(back.num_vertices(), 6);
        assert_eq!(back.face_groups, vec![0, 0, 0, 0, 1, 1, 1, 1]);
    }

    #[test]
    fn broken_files_are_clear_errors() {
        let bytes = write_glb(&octahedron(), &WriteParams::default()).unwrap();
        let e = read_glb(&bytes[..bytes.len() - 10])
            .unwrap_err()
            .to_string();
        assert!(e.contains("truncated"), "{e}");
        let e = read_glb(b"PK\x03\x04 not a glb").unwrap_err().to_string();
        assert!(e.contains("does not start with \"glTF\""), "{e}");
        let e = write_glb(&TriMesh::default(), &WriteParams::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("no faces"), "{e}");
    }
}
