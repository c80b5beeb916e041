//! Benchmarks of `fem-static`'s building blocks on box beams of linear tetrahedra (6-split):
//! assembly (pattern + values), symbolic + numeric Cholesky of the clamped stiffness, and one
//! solve. Sizes: ~10k tetrahedra (30×8×7 cells) and ~100k (60×16×18 cells).

use std::hint::black_box;

use criterion::Criterion;

#[path = "support/cpu_time.rs"]
mod cpu_time;
use tissue::Material;
use tissue::math::{Real, Vec3};
use tissue::mesh::TetMesh;
use tissue::mesh::generate::{BoxSplit, box_tets};
use tissue::model::fem::{Assembler, element_linear};
use tissue::solve::{BlockPattern, SparseCholesky};

fn beam(cells: [usize; 3]) -> TetMesh {
    let size = Vec3::new(cells[0] as Real, cells[1] as Real, cells[2] as Real) * 0.01;
    box_tets(Vec3::ZERO, size, cells, BoxSplit::Six)
}

fn assemble(mesh: &TetMesh, material: &Material) -> (Assembler, Vec<Real>) {
    let asm = Assembler::new(mesh.vertices.len(), mesh.tets.concat(), 4).expect("valid mesh");
    let k = asm
        .assemble(|e, ke| {
            element_linear::stiffness(&mesh.corners(e), material)
                .map(|k| ke.copy_from_slice(k.as_flattened()))
                .is_some()
        })
        .expect("no flat tet");
    (asm, k)
}

/// K with the dofs of the nodes at x = 0 replaced by identity rows and columns (clamped end).
fn clamp(mesh: &TetMesh, pattern: &BlockPattern, k: &[Real]) -> Vec<Real> {
    let held: Vec<bool> = mesh.vertices.iter().flat_map(|x| [x.x == 0.0; 3]).collect();
    let mut a = k.to_vec();
    for c in 0..pattern.dim() {
        let range = pattern.col_ptr[c]..pattern.col_ptr[c + 1];
        for (v, &r) in a[range.clone()].iter_mut().zip(&pattern.row_idx[range]) {
            if (held[c] || held[r]) && r != c {
                *v = 0.0;
            }
        }
    }
    a
}

fn bench(c: &mut Criterion<cpu_time::ThreadCpuTime>) {
    let material = Material::new(1.0e4, 0.45).expect("valid material");
    for (name, cells) in [("10k", [30, 8, 7]), ("100k", [60, 16, 18])] {
        let mesh = beam(cells);
        let mut group = c.benchmark_group("fem_static");
        group.sample_size(10);
        group.bench_function(format!("assemble/{name}"), |b| {
            b.iter(|| black_box(assemble(&mesh, &material)))
        });
        let (asm, k) = assemble(&mesh, &material);
        let a = clamp(&mesh, &asm.pattern, &k);
        group.bench_function(format!("factorize/{name}"), |b| {
            b.iter(|| {
                let mut chol = SparseCholesky::new(&asm.pattern).expect("symbolic");
                chol.factorize(&asm.pattern, &a, "")
                    .expect("clamped beam is SPD");
                black_box(chol.factor_nnz())
            })
        });
        let mut chol = SparseCholesky::new(&asm.pattern).expect("symbolic");
        chol.factorize(&asm.pattern, &a, "")
            .expect("clamped beam is SPD");
        let rhs: Vec<Real> = (0..asm.pattern.dim())
            .map(|i| if i % 3 == 2 { -1e-3 } else { 0.0 })
            .collect();
        let mut x = rhs.clone();
        group.bench_function(format!("solve/{name}"), |b| {
            b.iter(|| {
                x.copy_from_slice(&rhs);
                chol.solve_in_place(&mut x).expect("factored");
                black_box(x[0])
            })
        });
        eprintln!(
            "fem_static {name}: {} tets, {} dofs, nnz(K) {}, nnz(L) {}",
            mesh.tets.len(),
            asm.pattern.dim(),
            asm.pattern.nnz(),
            chol.factor_nnz()
        );
        group.finish();
    }
}

cpu_time::cpu_time_main!(bench);
