//! Press one vertex of the SOFA liver 5 mm inwards with the reference static FEM and print the
//! force an instrument would feel. Run: `cargo run --release -p tissue --example press_liver`.

use tissue::interact::{Constraints, Prescribed, Region};
use tissue::model::Deformable;
use tissue::model::fem::{FemStatic, Order};

fn main() -> Result<(), tissue::Error> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/meshes/liver.msh");
    let mut mesh = tissue::io::read(path)?;
    for v in &mut mesh.vertices {
        *v *= 0.01; // the file is in centimetres
    }
    let material = tissue::Material::new(3000.0, 0.3)?;
    let mut liver = FemStatic::new(&mesh.tet_mesh(path)?, material, Order::Linear)?;

    // Hold the bottom 5 mm of the liver; press the highest surface vertex down by 5 mm.
    let positions = liver.surface().positions.to_vec();
    let low = positions.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
    let fixed = Region::Box {
        min: [-1.0, -1.0, -1.0],
        max: [1.0, low + 0.005, 1.0],
    };
    let top = (0..positions.len()).max_by(|&a, &b| positions[a].y.total_cmp(&positions[b].y));
    let top = top.unwrap_or(0);
    let target = positions[top] - tissue::Vec3::Y * 0.005;
    liver.set_constraints(&Constraints {
        fixed: fixed.select(&positions),
        prescribed: vec![Prescribed {
            vertex: top as u32,
            position: target,
        }],
    })?;
    liver.step(0.0)?; // static: solves K u = f
    let force = liver.reactions().prescribed[0];
    println!(
        "pressed surface vertex {top} by 5 mm: the tissue pushes back with {:.4} N ({:.4}, {:.4}, {:.4})",
        force.length(),
        force.x,
        force.y,
        force.z
    );
    Ok(())
}
