//! `tissue mesh inspect | convert | repair`.

use anyhow::Context;
use tissue::io::{self, Format, MshVersion, WriteOptions};
use tissue::mesh::MeshData;
use tissue::mesh::inspect::inspect;
use tissue::mesh::repair::{RepairOptions, repair};

use crate::MeshCommand;

pub fn mesh(cmd: &MeshCommand) -> anyhow::Result<()> {
    match cmd {
        MeshCommand::Inspect { file, json } => {
            let mesh = io::read(file)?;
            let report = inspect(&mesh);
            if *json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                println!("{}", file.display());
                print!("{report}");
            }
            Ok(())
        }
        MeshCommand::Convert {
            input,
            output,
            msh_version,
            ascii,
        } => {
            let format = Format::from_path(output)?;
            anyhow::ensure!(
                format.can_write(),
                "{}: tissue reads this format but does not write it",
                output.display()
            );
            let mesh = io::read(input)?;
            let options = WriteOptions {
                msh_version: if *msh_version == 2 {
                    MshVersion::V2
                } else {
                    MshVersion::V4
                },
                binary: !*ascii,
            };
            io::write_with(output, &mesh, &options)?;
            println!("wrote {}: {}", output.display(), counts(&mesh));
            Ok(())
        }
        MeshCommand::Repair {
            input,
            output,
            tolerance,
        } => {
            let format = Format::from_path(output)?;
            anyhow::ensure!(
                format.can_write(),
                "{}: cannot write this format",
                output.display()
            );
            let mut mesh = io::read(input)?;
            let options = RepairOptions {
                merge_tolerance: Some(*tolerance),
                ..RepairOptions::default()
            };
            let report = repair(&mut mesh, &options);
            io::write(output, &mesh)
                .with_context(|| format!("writing the repaired mesh of {}", input.display()))?;
            println!("{report}");
            println!("wrote {}: {}", output.display(), counts(&mesh));
            Ok(())
        }
    }
}

fn counts(mesh: &MeshData) -> String {
    let mut parts = vec![format!("{} vertices", mesh.vertices.len())];
    for (n, what) in [
        (mesh.triangles.len(), "triangles"),
        (mesh.tets.len(), "tetrahedra"),
        (mesh.tets10.len(), "10-node tetrahedra"),
    ] {
        if n > 0 {
            parts.push(format!("{n} {what}"));
        }
    }
    parts.join(", ")
}
