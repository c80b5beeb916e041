use tissue::Material;
use tissue::math::{Real, Vec3};
use tissue::mesh::generate::{BoxSplit, box_tets};
use tissue::model::fem::{CorotationalParams, FemCorotational};
fn main() {
    let steps: usize = std::env::args().nth(1).unwrap().parse().unwrap();
    let cells = [40, 8, 10];
    let size = Vec3::new(cells[0] as Real, cells[1] as Real, cells[2] as Real) * 0.01;
    let mesh = box_tets(Vec3::ZERO, size, cells, BoxSplit::Six);
    let clamped: Vec<usize> = (0..mesh.vertices.len()).filter(|&i| mesh.vertices[i].x == 0.0).collect();
    let material = Material::new(1.0e5, 0.45).unwrap();
    let params = CorotationalParams { cg_iterations: 20, cg_tolerance: 1e-10 };
    let mut m = FemCorotational::new(&mesh, material, params).unwrap();
    m.set_node_constraints(&clamped, &[]).unwrap();
    m.set_node_loads(Vec3::new(0.0, -9.81, 0.0), &[]).unwrap();
    let t = std::time::Instant::now();
    for _ in 0..steps { m.advance(0.01).unwrap(); }
    eprintln!("{} tets {} nodes: {:.2} ms/step", mesh.tets.len(), mesh.vertices.len(), t.elapsed().as_secs_f64()*1e3/steps as f64);
}
