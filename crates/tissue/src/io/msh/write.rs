//! Gmsh writers: v2.2 ascii and binary, v4.1 ascii. No `$PhysicalNames`: the physical tag of
//! each element is written as a number (0 when the mesh has no tags). Elements are written
//! triangles, then tetrahedra, then 10-node tetrahedra (converted to Gmsh's node order), so a
//! file read back gives the same arrays.

use std::fmt::Write;

use super::swap_tet10_order;
use crate::mesh::MeshData;

/// One element in Gmsh terms: type, physical tag (0 = none), 0-based nodes in Gmsh order.
struct Elem {
    ty: i32,
    phys: i32,
    nodes: [u32; 10],
    n: usize,
}

impl Elem {
    fn nodes(&self) -> &[u32] {
        &self.nodes[..self.n]
    }
}

fn elements(mesh: &MeshData) -> Vec<Elem> {
    let tag = |tags: &[i32], i: usize| tags.get(i).copied().unwrap_or(0);
    let mut out = Vec::with_capacity(mesh.triangles.len() + mesh.tets.len() + mesh.tets10.len());
    for (i, t) in mesh.triangles.iter().enumerate() {
        let mut nodes = [0; 10];
        nodes[..3].copy_from_slice(t);
        out.push(Elem {
            ty: 2,
            phys: tag(&mesh.triangle_tags, i),
            nodes,
            n: 3,
        });
    }
    for (i, t) in mesh.tets.iter().enumerate() {
        let mut nodes = [0; 10];
        nodes[..4].copy_from_slice(t);
        out.push(Elem {
            ty: 4,
            phys: tag(&mesh.tet_tags, i),
            nodes,
            n: 4,
        });
    }
    for t in &mesh.tets10 {
        out.push(Elem {
            ty: 11,
            phys: 0,
            nodes: swap_tet10_order(*t),
            n: 10,
        });
    }
    out
}

/// Gmsh wants a positive elementary (entity) tag: the physical tag when it is one.
fn elementary(phys: i32) -> i32 {
    if phys > 0 { phys } else { 1 }
}

/// Shortest text that reads back to the same f64.
fn real(out: &mut String, v: f64) {
    let _ = write!(out, "{v:?}");
}

fn node_lines(out: &mut String, mesh: &MeshData) {
    for (i, p) in mesh.vertices.iter().enumerate() {
        let _ = write!(out, "{}", i + 1);
        for v in p.to_array() {
            out.push(' ');
            real(out, v);
        }
        out.push('\n');
    }
}

pub(super) fn encode_v2(mesh: &MeshData) -> Result<Vec<u8>, String> {
    let mut out = String::from("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n");
    let _ = writeln!(out, "{}", mesh.vertices.len());
    node_lines(&mut out, mesh);
    out.push_str("$EndNodes\n$Elements\n");
    let elems = elements(mesh);
    let _ = writeln!(out, "{}", elems.len());
    for (i, e) in elems.iter().enumerate() {
        let _ = write!(
            out,
            "{} {} 2 {} {}",
            i + 1,
            e.ty,
            e.phys,
            elementary(e.phys)
        );
        for &v in e.nodes() {
            let _ = write!(out, " {}", u64::from(v) + 1);
        }
        out.push('\n');
    }
    out.push_str("$EndElements\n");
    Ok(out.into_bytes())
}

/// Gmsh v2.2 binary, little-endian: the same content as the ascii writer.
pub fn encode_v2_binary(mesh: &MeshData) -> Result<Vec<u8>, String> {
    let int =
        |v: usize| i32::try_from(v).map_err(|_| format!("{v} does not fit a Gmsh binary int"));
    let mut out = b"$MeshFormat\n2.2 1 8\n".to_vec();
    out.extend(1i32.to_le_bytes());
    out.extend(b"\n$EndMeshFormat\n$Nodes\n");
    out.extend(format!("{}\n", mesh.vertices.len()).as_bytes());
    for (i, p) in mesh.vertices.iter().enumerate() {
        out.extend(int(i + 1)?.to_le_bytes());
        for v in p.to_array() {
            out.extend(v.to_le_bytes());
        }
    }
    out.extend(b"\n$EndNodes\n$Elements\n");
    let elems = elements(mesh);
    out.extend(format!("{}\n", elems.len()).as_bytes());
    let mut start = 0;
    while start < elems.len() {
        let ty = elems[start].ty;
        let len = elems[start..].iter().take_while(|e| e.ty == ty).count();
        for h in [ty, int(len)?, 2] {
            out.extend(h.to_le_bytes());
        }
        for (i, e) in elems[start..start + len].iter().enumerate() {
            for h in [int(start + i + 1)?, e.phys, elementary(e.phys)] {
                out.extend(h.to_le_bytes());
            }
            for &v in e.nodes() {
                out.extend(int(v as usize + 1)?.to_le_bytes());
            }
        }
        start += len;
    }
    out.extend(b"\n$EndElements\n");
    Ok(out)
}

/// Entity tags of one dimension: the physical tag itself when positive, fresh tags above all
/// positive ones for 0 (no group) and negative tags.
fn entity_tags(phys: impl Iterator<Item = i32>) -> Vec<(i32, i32)> {
    let mut distinct: Vec<i32> = Vec::new();
    for p in phys {
        if !distinct.contains(&p) {
            distinct.push(p);
        }
    }
    let mut next = distinct
        .iter()
        .copied()
        .filter(|&p| p > 0)
        .max()
        .unwrap_or(0);
    distinct
        .into_iter()
        .map(|p| {
            if p > 0 {
                (p, p)
            } else {
                next += 1;
                (next, p)
            }
        })
        .collect()
}

pub(super) fn encode_v4(mesh: &MeshData) -> Result<Vec<u8>, String> {
    let elems = elements(mesh);
    let dim = |ty: i32| if ty == 2 { 2 } else { 3 };
    let surfaces = entity_tags(elems.iter().filter(|e| dim(e.ty) == 2).map(|e| e.phys));
    let mut volumes = entity_tags(elems.iter().filter(|e| dim(e.ty) == 3).map(|e| e.phys));
    if surfaces.is_empty() && volumes.is_empty() {
        volumes.push((1, 0));
    }
    let entity_of = |d: i32, phys: i32| {
        let list = if d == 2 { &surfaces } else { &volumes };
        list.iter()
            .find(|&&(_, p)| p == phys)
            .map_or(1, |&(t, _)| t)
    };

    let (lo, hi) = bounds(mesh);
    let mut out = String::from("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n");
    let _ = writeln!(out, "0 0 {} {}", surfaces.len(), volumes.len());
    for &(tag, phys) in surfaces.iter().chain(&volumes) {
        let _ = write!(out, "{tag}");
        for v in lo.iter().chain(&hi) {
            out.push(' ');
            real(&mut out, *v);
        }
        if phys == 0 {
            out.push_str(" 0 0\n");
        } else {
            let _ = writeln!(out, " 1 {phys} 0");
        }
    }
    out.push_str("$EndEntities\n$Nodes\n");
    // All nodes go in one block on the first entity of the highest dimension.
    let (node_dim, node_entity) = match volumes.first() {
        Some(&(t, _)) => (3, t),
        None => (2, surfaces.first().map_or(1, |&(t, _)| t)),
    };
    let n = mesh.vertices.len();
    if n == 0 {
        out.push_str("0 0 0 0\n");
    } else {
        let _ = writeln!(out, "1 {n} 1 {n}\n{node_dim} {node_entity} 0 {n}");
        for i in 1..=n {
            let _ = writeln!(out, "{i}");
        }
        for p in &mesh.vertices {
            for (k, v) in p.to_array().into_iter().enumerate() {
                if k > 0 {
                    out.push(' ');
                }
                real(&mut out, v);
            }
            out.push('\n');
        }
    }
    out.push_str("$EndNodes\n$Elements\n");
    // A new block whenever the type or the tag changes, so the element order is kept.
    let mut blocks = Vec::new();
    let mut start = 0;
    while start < elems.len() {
        let (ty, phys) = (elems[start].ty, elems[start].phys);
        let len = elems[start..]
            .iter()
            .take_while(|e| e.ty == ty && e.phys == phys)
            .count();
        blocks.push((start, len));
        start += len;
    }
    let m = elems.len();
    let _ = writeln!(out, "{} {m} {} {m}", blocks.len(), usize::from(m > 0));
    for (start, len) in blocks {
        let e0 = &elems[start];
        let d = dim(e0.ty);
        let _ = writeln!(out, "{d} {} {} {len}", entity_of(d, e0.phys), e0.ty);
        for (i, e) in elems[start..start + len].iter().enumerate() {
            let _ = write!(out, "{}", start + i + 1);
            for &v in e.nodes() {
                let _ = write!(out, " {}", u64::from(v) + 1);
            }
            out.push('\n');
        }
    }
    out.push_str("$EndElements\n");
    Ok(out.into_bytes())
}

fn bounds(mesh: &MeshData) -> ([f64; 3], [f64; 3]) {
    let mut it = mesh.vertices.iter();
    let Some(first) = it.next() else {
        return ([0.0; 3], [0.0; 3]);
    };
    let (lo, hi) = it.fold((*first, *first), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    (lo.to_array(), hi.to_array())
}
