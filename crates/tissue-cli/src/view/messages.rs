//! The WebSocket messages from the page, and their validation. Everything the page sends is
//! untrusted: size is capped before parsing, unknown types and fields are rejected, numbers
//! must be finite and positions near the organ, kinds must be built in. A rejected message
//! becomes an error shown on the page and logged; the simulation never sees it.

use serde::Deserialize;
use tissue::model::KINDS;
use tissue::{Material, Real, Vec3};

/// Largest message accepted, in bytes (a long scalpel path is ~10 KiB).
pub const MAX_MESSAGE_BYTES: usize = 16 * 1024;
/// Most points in one scalpel path.
pub const MAX_CUT_POINTS: usize = 256;

/// A command from the page, checked.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// Moves the probe to a point, or parks it away from the organ (`None`).
    Probe(Option<Vec3>),
    /// Closes the grasper at a point (the first time) or carries it there.
    Grasp(Vec3),
    /// Opens the grasper.
    Release,
    /// A scalpel path over the surface, and the direction into the organ (unit).
    Cut {
        path: Vec<Vec3>,
        into: Vec3,
    },
    /// Rebuilds the model with another kind.
    SetModel(String),
    /// Rebuilds the model with another material (E, ν; density and damping kept).
    SetMaterial {
        young_modulus: Real,
        poisson_ratio: Real,
    },
    Reset,
}

#[derive(Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
enum Raw {
    Probe {
        position: Option<[Real; 3]>,
    },
    Grasp {
        position: [Real; 3],
    },
    // Empty braces, not unit variants: serde's deny_unknown_fields skips unit variants.
    Release {},
    Cut {
        path: Vec<[Real; 3]>,
        into: [Real; 3],
    },
    SetModel {
        kind: String,
    },
    SetMaterial {
        young_modulus: Real,
        poisson_ratio: Real,
    },
    Reset {},
}

/// Where positions may be: a ball around the organ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub center: Vec3,
    pub radius: Real,
}

impl Bounds {
    fn point(&self, p: [Real; 3], what: &str) -> Result<Vec3, String> {
        let v = Vec3::from(p);
        if !tissue::math::is_finite_vec(v) {
            return Err(format!("{what}: coordinates must be finite numbers"));
        }
        if v.distance(self.center) > self.radius {
            return Err(format!(
                "{what}: {v:?} is farther than {:.3} m from the organ",
                self.radius
            ));
        }
        Ok(v)
    }
}

/// Parses and checks one text message.
pub fn parse(text: &str, bounds: &Bounds) -> Result<Command, String> {
    if text.len() > MAX_MESSAGE_BYTES {
        return Err(format!(
            "message of {} bytes rejected: the limit is {MAX_MESSAGE_BYTES}",
            text.len()
        ));
    }
    let raw: Raw = serde_json::from_str(text).map_err(|e| format!("malformed message: {e}"))?;
    Ok(match raw {
        Raw::Probe { position } => Command::Probe(
            position
                .map(|p| bounds.point(p, "probe position"))
                .transpose()?,
        ),
        Raw::Grasp { position } => Command::Grasp(bounds.point(position, "grasp position")?),
        Raw::Release {} => Command::Release,
        Raw::Cut { path, into } => {
            if path.len() < 2 || path.len() > MAX_CUT_POINTS {
                return Err(format!(
                    "cut path of {} points: needs 2 to {MAX_CUT_POINTS}",
                    path.len()
                ));
            }
            let path = path
                .into_iter()
                .map(|p| bounds.point(p, "cut path point"))
                .collect::<Result<Vec<_>, _>>()?;
            let into = Vec3::from(into);
            let n = into.length();
            if !(n.is_finite() && n > 1e-9) {
                return Err("cut direction must be a finite non-zero vector".into());
            }
            Command::Cut {
                path,
                into: into / n,
            }
        }
        Raw::SetModel { kind } => {
            if !KINDS.iter().any(|k| k.name == kind) {
                let known: Vec<&str> = KINDS.iter().map(|k| k.name).collect();
                return Err(format!(
                    "unknown model kind `{}`; built in: {}",
                    kind.chars().take(64).collect::<String>(),
                    known.join(", ")
                ));
            }
            Command::SetModel(kind)
        }
        Raw::SetMaterial {
            young_modulus,
            poisson_ratio,
        } => {
            Material {
                young_modulus,
                poisson_ratio,
                density: 1000.0,
                damping: 0.0,
                stiffness_damping: 0.0,
            }
            .validated()
            .map_err(|e| format!("material rejected: {e}"))?;
            Command::SetMaterial {
                young_modulus,
                poisson_ratio,
            }
        }
        Raw::Reset {} => Command::Reset,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn b() -> Bounds {
        Bounds {
            center: Vec3::new(0.0, 0.05, 0.0),
            radius: 0.5,
        }
    }

    fn err(text: &str) -> String {
        match parse(text, &b()) {
            Err(e) => e,
            Ok(c) => panic!("accepted {text}: {c:?}"),
        }
    }

    #[test]
    fn good_messages() {
        assert_eq!(
            parse(r#"{"type":"probe","position":[0.01,0.02,0.03]}"#, &b()),
            Ok(Command::Probe(Some(Vec3::new(0.01, 0.02, 0.03))))
        );
        assert_eq!(
            parse(r#"{"type":"probe","position":null}"#, &b()),
            Ok(Command::Probe(None))
        );
        assert_eq!(parse(r#"{"type":"reset"}"#, &b()), Ok(Command::Reset));
        assert_eq!(parse(r#"{"type":"release"}"#, &b()), Ok(Command::Release));
        let kind = KINDS.first().map_or("", |k| k.name);
        assert_eq!(
            parse(&format!(r#"{{"type":"set_model","kind":"{kind}"}}"#), &b()),
            Ok(Command::SetModel(kind.to_string()))
        );
        assert_eq!(
            parse(
                r#"{"type":"cut","path":[[0,0,0],[0.01,0,0]],"into":[0,-2,0]}"#,
                &b()
            ),
            Ok(Command::Cut {
                path: vec![Vec3::ZERO, Vec3::new(0.01, 0.0, 0.0)],
                into: Vec3::new(0.0, -1.0, 0.0)
            })
        );
        assert_eq!(
            parse(
                r#"{"type":"set_material","young_modulus":5000,"poisson_ratio":0.45}"#,
                &b()
            ),
            Ok(Command::SetMaterial {
                young_modulus: 5000.0,
                poisson_ratio: 0.45
            })
        );
    }

    #[test]
    fn malformed_messages_are_rejected_with_a_reason() {
        assert!(err("not json").starts_with("malformed message"));
        assert!(err("{}").starts_with("malformed message"));
        assert!(err(r#"{"type":"explode"}"#).contains("unknown variant"));
        assert!(err(r#"{"type":"reset","extra":1}"#).contains("unknown field"));
        assert!(err(r#"{"type":"probe","position":[1,2]}"#).starts_with("malformed"));
        assert!(err(r#"{"type":"probe","position":["a",0,0]}"#).starts_with("malformed"));
        // JSON has no NaN; a huge exponent overflows to infinity in serde_json and is refused.
        assert!(err(r#"{"type":"grasp","position":[1e400,0,0]}"#).starts_with("malformed"));
        assert!(err(r#"{"type":"grasp","position":[3,0,0]}"#).contains("farther than"));
        assert!(err(r#"{"type":"set_model","kind":"no-such"}"#).contains("unknown model kind"));
        assert!(
            err(r#"{"type":"set_material","young_modulus":-1,"poisson_ratio":0.3}"#)
                .starts_with("material rejected")
        );
        assert!(
            err(r#"{"type":"set_material","young_modulus":1000,"poisson_ratio":0.5}"#)
                .starts_with("material rejected")
        );
        assert!(err(r#"{"type":"cut","path":[[0,0,0]],"into":[0,1,0]}"#).contains("1 points"));
        assert!(
            err(r#"{"type":"cut","path":[[0,0,0],[0,0,0]],"into":[0,0,0]}"#).contains("non-zero")
        );
    }

    #[test]
    fn oversized_messages_are_rejected_before_parsing() {
        let big = format!(
            r#"{{"type":"reset","pad":"{}"}}"#,
            "x".repeat(MAX_MESSAGE_BYTES)
        );
        let e = err(&big);
        assert!(e.contains("bytes rejected"), "{e}");
        assert!(
            e.contains(&format!("message of {} bytes", big.len())),
            "{e}"
        );
        // Just under the limit with a too-long path: rejected by count, not size.
        let pts: Vec<String> = (0..300).map(|_| "[0,0,0]".to_string()).collect();
        let msg = format!(
            r#"{{"type":"cut","path":[{}],"into":[0,1,0]}}"#,
            pts.join(",")
        );
        assert!(msg.len() < MAX_MESSAGE_BYTES);
        assert!(err(&msg).contains("300 points"));
    }
}
