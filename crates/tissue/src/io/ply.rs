//! PLY reader (ascii, binary little and big endian) with OpenSurgSim's custom elements:
//! `vertex` (x, y, z), `face` (vertex_indices, fan-split), `3d_element` (tetrahedra),
//! `boundary_condition` (fixed vertices) and `material`. Other elements are read past using
//! their declared properties, so binary files with extra data still parse.

use std::path::Path;

use super::cursor::Cursor;
use crate::error::{IoError, Location};
use crate::math::Vec3;
use crate::mesh::{MaterialRecord, MeshData};

mod header;

use header::{Element, Encoding, Kind, Scalar, parse_header};

/// What a known element contributes to the mesh; property positions within a record.
enum Role {
    Vertex([usize; 3]),
    Face(usize),
    Tet(usize),
    Fixed(usize),
    Material([usize; 3]),
    Skip,
}

/// Reads a PLY file.
pub fn parse(bytes: &[u8], path: &Path) -> Result<MeshData, IoError> {
    let mut c = Cursor::new(path, bytes);
    let (encoding, elements) = parse_header(&mut c)?;
    let mut mesh = MeshData::default();
    let mut rec = Record::default();
    for e in &elements {
        let role = role_of(e, path)?;
        if e.props.is_empty() {
            // Nothing to read, and a huge count must not spin.
            continue;
        }
        let remaining = bytes.len().saturating_sub(c.position());
        let cap = (e
            .count
            .min((remaining / e.min_record_bytes(encoding != Encoding::Ascii)) as u64))
            as usize;
        match role {
            Role::Vertex(_) => mesh.vertices.reserve(cap),
            Role::Face(_) => mesh.triangles.reserve(cap),
            Role::Tet(_) => mesh.tets.reserve(cap),
            Role::Fixed(_) => mesh.fixed_vertices.reserve(cap),
            Role::Material(_) | Role::Skip => {}
        }
        for i in 0..e.count {
            let at = rec.read(&mut c, e, encoding, bytes.len(), i)?;
            let err = |msg: String| match encoding {
                Encoding::Ascii => c.error(msg),
                Encoding::Binary { .. } => IoError::new(path, Location::Byte(at as u64), msg),
            };
            match role {
                Role::Vertex([x, y, z]) => {
                    let v = Vec3::new(rec.scalar(x), rec.scalar(y), rec.scalar(z));
                    if !crate::math::is_finite_vec(v) {
                        return Err(err(format!("vertex {i} has a non-finite coordinate")));
                    }
                    mesh.vertices.push(v);
                }
                Role::Face(p) => {
                    let poly = rec.indices(p).map_err(|m| err(format!("face {i}: {m}")))?;
                    if poly.len() < 3 {
                        return Err(err(format!(
                            "face {i} has {} vertices; at least 3 are needed",
                            poly.len()
                        )));
                    }
                    super::obj::fan_split(&poly, &mut mesh.triangles);
                }
                Role::Tet(p) => {
                    let ids = rec
                        .indices(p)
                        .map_err(|m| err(format!("{} {i}: {m}", e.name)))?;
                    match <[u32; 4]>::try_from(ids.as_slice()) {
                        Ok(t) => mesh.tets.push(t),
                        Err(_) => {
                            return Err(err(format!(
                                "{} {i} has {} vertices; only 4-node tetrahedra are supported",
                                e.name,
                                ids.len()
                            )));
                        }
                    }
                }
                Role::Fixed(p) => {
                    let v = rec.scalar(p);
                    let v = to_index(v).map_err(|m| err(format!("{} {i}: {m}", e.name)))?;
                    mesh.fixed_vertices.push(v);
                }
                Role::Material(p) => {
                    let [rho, nu, young] = p.map(|k| rec.scalar(k));
                    if ![rho, nu, young].iter().all(|v| v.is_finite()) {
                        return Err(err(format!("material {i} has a non-finite value")));
                    }
                    if mesh.material.is_none() {
                        mesh.material = Some(MaterialRecord {
                            density: rho,
                            poisson_ratio: nu,
                            young_modulus: young,
                        });
                    }
                }
                Role::Skip => {}
            }
        }
    }
    Ok(mesh)
}

fn role_of(e: &Element, path: &Path) -> Result<Role, IoError> {
    let missing = |what: &str| {
        IoError::new(
            path,
            Location::Line(e.line),
            format!("element `{}` has no {what} property", e.name),
        )
    };
    let scalar = |name: &str| match e.find(name) {
        Some(k) if matches!(e.props[k].kind, Kind::Scalar(_)) => Ok(k),
        _ => Err(missing(&format!("scalar `{name}`"))),
    };
    let list = |names: &[&str]| {
        names
            .iter()
            .find_map(|n| e.find(n))
            .or_else(|| {
                e.props
                    .iter()
                    .position(|p| matches!(p.kind, Kind::List { .. }))
            })
            .filter(|&k| matches!(e.props[k].kind, Kind::List { .. }))
            .ok_or_else(|| missing("list `vertex_indices`"))
    };
    Ok(match e.name.as_str() {
        "vertex" => Role::Vertex([scalar("x")?, scalar("y")?, scalar("z")?]),
        "face" => Role::Face(list(&["vertex_indices", "vertex_index"])?),
        "3d_element" => Role::Tet(list(&["vertex_indices", "vertex_index"])?),
        "boundary_condition" => Role::Fixed(scalar("vertex_index")?),
        "material" => Role::Material([
            scalar("mass_density")?,
            scalar("poisson_ratio")?,
            scalar("young_modulus")?,
        ]),
        _ => Role::Skip,
    })
}

fn to_index(v: f64) -> Result<u32, String> {
    if v.fract() == 0.0 && (0.0..=f64::from(u32::MAX)).contains(&v) {
        Ok(v as u32)
    } else {
        Err(format!("`{v}` is not a valid vertex index"))
    }
}

/// One element record: every value as f64 (exact for all integer types), with the span of
/// each property; reused between records.
#[derive(Default)]
struct Record {
    values: Vec<f64>,
    spans: Vec<(usize, usize)>,
}

impl Record {
    fn scalar(&self, prop: usize) -> f64 {
        self.spans
            .get(prop)
            .and_then(|&(s, _)| self.values.get(s))
            .copied()
            .unwrap_or(f64::NAN)
    }

    fn indices(&self, prop: usize) -> Result<Vec<u32>, String> {
        let (s, e) = self.spans.get(prop).copied().unwrap_or((0, 0));
        self.values
            .get(s..e)
            .unwrap_or(&[])
            .iter()
            .map(|&v| to_index(v))
            .collect()
    }

    /// Reads record `i` of element `e`; returns the byte offset where it started.
    fn read(
        &mut self,
        c: &mut Cursor<'_>,
        e: &Element,
        encoding: Encoding,
        len: usize,
        i: u64,
    ) -> Result<usize, IoError> {
        self.values.clear();
        self.spans.clear();
        let start = c.position();
        match encoding {
            Encoding::Ascii => {
                let line = c.next_nonblank()?.ok_or_else(|| {
                    c.error(format!(
                        "unexpected end of file, expected {} {} of {}",
                        e.name, i, e.count
                    ))
                })?;
                let mut t = line.split_whitespace();
                for p in &e.props {
                    let s = self.values.len();
                    let mut next = |what: &str| {
                        t.next().ok_or_else(|| {
                            c.error(format!(
                                "{} {i}: the line ends before {what} `{}`",
                                e.name, p.name
                            ))
                        })
                    };
                    match p.kind {
                        Kind::Scalar(ty) => {
                            let tok = next("property")?;
                            self.values.push(ascii_value(c, tok, ty)?);
                        }
                        Kind::List { item, .. } => {
                            let n: usize = c.parse(next("the count of list")?, "a list count")?;
                            for _ in 0..n {
                                let tok = next("an item of list")?;
                                self.values.push(ascii_value(c, tok, item)?);
                            }
                        }
                    }
                    self.spans.push((s, self.values.len()));
                }
                if let Some(extra) = t.next() {
                    return Err(c.error(format!(
                        "{} {i}: unexpected value `{extra}` after the declared properties",
                        e.name
                    )));
                }
            }
            Encoding::Binary { big } => {
                for p in &e.props {
                    let s = self.values.len();
                    match p.kind {
                        Kind::Scalar(ty) => self.values.push(ty.decode(c.take(ty.size())?, big)),
                        Kind::List { count, item } => {
                            let at = c.position();
                            let n = count.decode(c.take(count.size())?, big);
                            let left = len.saturating_sub(c.position());
                            // Counts are integers (checked in the header); a negative one
                            // is as wrong as one larger than the data.
                            let bytes_needed = (n >= 0.0)
                                .then(|| (n as usize).checked_mul(item.size()))
                                .flatten()
                                .filter(|&b| b <= left);
                            let Some(b) = bytes_needed else {
                                return Err(IoError::new(
                                    c.path(),
                                    Location::Byte(at as u64),
                                    format!(
                                        "{} {i}: list `{}` has {n} items, more than the {left} bytes left",
                                        e.name, p.name
                                    ),
                                ));
                            };
                            let data = c.take(b)?;
                            self.values.extend(
                                data.chunks_exact(item.size()).map(|d| item.decode(d, big)),
                            );
                        }
                    }
                    self.spans.push((s, self.values.len()));
                }
            }
        }
        Ok(start)
    }
}

fn ascii_value(c: &Cursor<'_>, tok: &str, ty: Scalar) -> Result<f64, IoError> {
    if ty.is_float() {
        c.parse::<f64>(tok, "a number")
    } else {
        Ok(c.parse::<i64>(tok, "an integer")? as f64)
    }
}

#[cfg(test)]
mod tests;
