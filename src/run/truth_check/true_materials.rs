//! The truth's materials (`truth/materials.json`: names, lobes and their colour weights
//! `λ`; `truth/weights.ply`: per-vertex blending weights), read once per run, and the true
//! reflectance `β_{x,b} = Σ_j w_{x,j} λ_{j,b}` in a basis for the truth check's floor.

use crate::run::Truth;
use crate::transport::brdf::BasisBrdf;
use crate::{Error, Result};

/// The truth's materials: per-vertex blending weights (row-major `V × J`), names and
/// lobe weights (`truth/weights.ply`, `truth/materials.json`), read once per run for the
/// truth check's floor and the albedo against the truth.
pub(crate) struct TrueMaterials {
    pub(super) names: Vec<String>,
    /// Index of the Lambertian lobe in `lobes`.
    pub(super) lambert: usize,
    pub(super) weights: Vec<f64>,
    /// Every lobe of the truth (`None`: a type this build does not know).
    pub(super) lobes: Vec<Option<BasisBrdf>>,
    /// `lambda[j][b]`: material `j`'s weight of lobe `b` per channel.
    pub(super) lambda: Vec<Vec<[f64; 3]>>,
}

impl TrueMaterials {
    /// `None` when the truth has no materials file, no Lambertian lobe or no weights.
    pub(crate) fn read(truth: &Truth) -> Result<Option<Self>> {
        let path = truth.dir.join("materials.json");
        let Ok(text) = std::fs::read_to_string(&path) else {
            return Ok(None);
        };
        let bad = |m: &str| Error::format(&path, "materials", m.to_string());
        let json: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| Error::format(&path, format!("line {}", e.line()), e.to_string()))?;
        let lobes = json["lobes"]
            .as_array()
            .ok_or_else(|| bad("no `lobes` list"))?;
        let Some(lt) = lobes.iter().position(|l| l["type"] == "lambert") else {
            return Ok(None);
        };
        let materials = json["materials"]
            .as_array()
            .ok_or_else(|| bad("no `materials` list"))?;
        let TrueLambda { names, lambda } = read_lambda(&path, materials, lobes.len())?;
        let Some(weights) = read_weights(&truth.dir.join("weights.ply"), names.len())? else {
            return Ok(None);
        };
        Ok(Some(TrueMaterials {
            names,
            lambert: lt,
            weights,
            lobes: lobes.iter().map(lobe_of).collect(),
            lambda,
        }))
    }

    /// The lobes some material of the truth uses, in the truth's order: the basis its
    /// reflectance is rendered in for the floor ([`add_true_reflectance`]). `None` when one
    /// of them is of a type this build does not know.
    pub(super) fn used_lobes(&self) -> Option<Vec<BasisBrdf>> {
        (0..self.lobes.len())
            .filter(|&b| self.lambda.iter().any(|m| m[b].iter().any(|&v| v != 0.0)))
            .map(|b| self.lobes[b])
            .collect()
    }

    /// Material `j`'s diffuse (Lambertian) albedo.
    pub(super) fn diffuse(&self, j: usize) -> [f64; 3] {
        self.lambda[j][self.lambert]
    }

    /// The true per-vertex weights `β_{x,b,c} = Σ_j w_j(x) λ_{j,b',c}` in the lobes of
    /// `basis` (row-major `V × B`), each truth lobe `b'` carried by the basis lobe equal to
    /// it; `None` when a truth lobe that any material uses is not in `basis` (or of a type
    /// this build does not know), or the weights are not `nv` rows.
    pub(super) fn beta_in_basis(&self, basis: &[BasisBrdf], nv: usize) -> Option<Vec<[f64; 3]>> {
        let (jj, nb) = (self.names.len(), basis.len());
        if jj == 0 || self.weights.len() != nv * jj {
            return None;
        }
        let mut to_basis = Vec::with_capacity(self.lobes.len());
        for (bt, lobe) in self.lobes.iter().enumerate() {
            let used = self.lambda.iter().any(|m| m[bt].iter().any(|&v| v != 0.0));
            let at = lobe.and_then(|l| basis.iter().position(|b| same_lobe(b, &l)));
            match (at, used) {
                (None, true) => return None,
                (at, _) => to_basis.push(at),
            }
        }
        let mut beta = vec![[0.0; 3]; nv * nb];
        for x in 0..nv {
            for (j, rows) in self.lambda.iter().enumerate() {
                let w = self.weights[x * jj + j];
                for (bt, at) in to_basis.iter().enumerate() {
                    if let Some(b) = at {
                        for c in 0..3 {
                            beta[x * nb + b][c] += w * rows[bt][c];
                        }
                    }
                }
            }
        }
        Some(beta)
    }
}

/// The truth's materials as `materials.json` lists them ([`read_lambda`]).
#[derive(Debug)]
struct TrueLambda {
    names: Vec<String>,
    /// Per material, per lobe, RGB.
    lambda: Vec<Vec<[f64; 3]>>,
}

/// Each material's name and per-lobe colour weights `λ` from the truth's
/// `materials.json` (`path`, for errors): `n_lobes` triples of numbers per material.
fn read_lambda(
    path: &std::path::Path,
    materials: &[serde_json::Value],
    n_lobes: usize,
) -> Result<TrueLambda> {
    let mut names = Vec::new();
    let mut lambda = Vec::new();
    for m in materials {
        let name = m["name"].as_str().unwrap_or("?").to_string();
        let mut rows = Vec::with_capacity(n_lobes);
        for b in 0..n_lobes {
            let d = &m["lambda"][b];
            let rgb = [0, 1, 2].map(|c| d[c].as_f64());
            if rgb.iter().any(Option::is_none) {
                return Err(Error::format(
                    path,
                    "materials",
                    format!("material `{name}`: the weight of lobe {b} is not three numbers"),
                ));
            }
            rows.push(rgb.map(|v| v.unwrap_or(0.0)));
        }
        names.push(name);
        lambda.push(rows);
    }
    Ok(TrueLambda { names, lambda })
}

/// The truth's blending weights from `weights.ply` (`w0 … w{j−1}` per vertex, vertex-major);
/// `None` when the file is absent.
fn read_weights(path: &std::path::Path, j: usize) -> Result<Option<Vec<f64>>> {
    let Ok(file) = std::fs::File::open(path) else {
        return Ok(None);
    };
    let ply = ply_rs::parser::Parser::<ply_rs::ply::DefaultElement>::new()
        .read_ply(&mut std::io::BufReader::new(file))
        .map_err(|_| Error::format(path, "header", "not a readable PLY file"))?;
    let verts = ply.payload.get("vertex").map_or(&[][..], |v| v.as_slice());
    let mut weights = Vec::with_capacity(verts.len() * j);
    for (x, v) in verts.iter().enumerate() {
        for m in 0..j {
            let w = match v.get(&format!("w{m}")) {
                Some(ply_rs::ply::Property::Float(w)) => *w as f64,
                Some(ply_rs::ply::Property::Double(w)) => *w,
                _ => {
                    return Err(Error::format(
                        path,
                        format!("vertex {x}"),
                        format!("no float property w{m}"),
                    ))
                }
            };
            weights.push(w);
        }
    }
    Ok(Some(weights))
}

/// A truth lobe of `materials.json` (`{"type": "lambert" | "phong", "exponent" | "ggx",
/// "alpha"}`) as a basis BRDF; `None` for another type.
fn lobe_of(l: &serde_json::Value) -> Option<BasisBrdf> {
    match l["type"].as_str()? {
        "lambert" => Some(BasisBrdf::Lambert),
        "phong" => Some(BasisBrdf::Phong {
            exponent: l["exponent"].as_f64()?,
        }),
        "ggx" => Some(BasisBrdf::Ggx {
            alpha: l["alpha"].as_f64()?,
        }),
        _ => None,
    }
}

/// Whether two lobes are the same BRDF (parameters within 1e-9 relative).
fn same_lobe(a: &BasisBrdf, b: &BasisBrdf) -> bool {
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-9 * x.abs().max(y.abs());
    match (a, b) {
        (BasisBrdf::Lambert, BasisBrdf::Lambert) => true,
        (BasisBrdf::Phong { exponent: x }, BasisBrdf::Phong { exponent: y }) => close(*x, *y),
        (BasisBrdf::Ggx { alpha: x }, BasisBrdf::Ggx { alpha: y }) => close(*x, *y),
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The truth's `materials.json` and `weights.ply` readers: values as written, an
    /// absent weights file as "no truth to check", and bad records named by file, material
    /// or vertex.
    #[test]
    fn the_truth_readers_take_good_files_and_name_bad_records() {
        let dir =
            std::env::temp_dir().join(format!("relight-truth-readers-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let json = dir.join("materials.json");
        let good: serde_json::Value = serde_json::json!([
            {"name": "a", "lambda": [[0.1, 0.2, 0.3]]},
            {"name": "b", "lambda": [[0.4, 0.5, 0.6]]}
        ]);
        let TrueLambda { names, lambda } = read_lambda(&json, good.as_array().unwrap(), 1).unwrap();
        assert_eq!(names, ["a", "b"]);
        assert_eq!(lambda, [vec![[0.1, 0.2, 0.3]], vec![[0.4, 0.5, 0.6]]]);
        let short = serde_json::json!([{"name": "b", "lambda": [[0.4, 0.5]]}]);
        let e = read_lambda(&json, short.as_array().unwrap(), 1)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("materials.json") && e.contains("material `b`"),
            "{e}"
        );
        assert!(e.contains("lobe 0 is not three numbers"), "{e}");

        let ply = dir.join("weights.ply");
        assert!(read_weights(&ply, 2).unwrap().is_none());
        let header =
            |props: &str| format!("ply\nformat ascii 1.0\nelement vertex 2\n{props}end_header\n");
        let two = "property float w0\nproperty float w1\n";
        std::fs::write(&ply, header(two) + "0.25 0.75\n1 0\n").unwrap();
        assert_eq!(
            read_weights(&ply, 2).unwrap().unwrap(),
            [0.25, 0.75, 1.0, 0.0]
        );
        std::fs::write(&ply, header("property float w0\n") + "0.25\n1\n").unwrap();
        let e = read_weights(&ply, 2).unwrap_err().to_string();
        assert!(e.contains("weights.ply") && e.contains("vertex 0"), "{e}");
        assert!(e.contains("no float property w1"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn the_true_reflectance_goes_into_the_fits_basis_lobe_by_lobe() {
        // Two materials over lobes [lambert, phong 50], two vertices (one pure, one a
        // 0.25 / 0.75 blend); β by hand: Σ_j w_j λ_{j,b}, each truth lobe at the index of
        // the equal basis lobe, whatever the basis order.
        let t = TrueMaterials {
            names: vec!["a".into(), "b".into()],
            lambert: 0,
            weights: vec![1.0, 0.0, 0.25, 0.75],
            lobes: vec![
                Some(BasisBrdf::Lambert),
                Some(BasisBrdf::Phong { exponent: 50.0 }),
            ],
            lambda: vec![
                vec![[0.8, 0.4, 0.2], [0.1, 0.1, 0.1]],
                vec![[0.2, 0.3, 0.6], [0.0, 0.0, 0.0]],
            ],
        };
        let basis = [
            BasisBrdf::Phong { exponent: 50.0 },
            BasisBrdf::Ggx { alpha: 0.3 },
            BasisBrdf::Lambert,
        ];
        let b = t.beta_in_basis(&basis, 2).unwrap();
        let want = [
            [0.1, 0.1, 0.1],
            [0.0; 3],
            [0.8, 0.4, 0.2],
            [0.025, 0.025, 0.025],
            [0.0; 3],
            [0.35, 0.325, 0.5],
        ];
        for (got, w) in b.iter().zip(&want) {
            for c in 0..3 {
                assert!((got[c] - w[c]).abs() < 1e-12, "{b:?}");
            }
        }
        // A lobe the truth uses and the basis lacks (phong 50, or phong 500 ≠ 50): none.
        assert!(t.beta_in_basis(&[BasisBrdf::Lambert], 2).is_none());
        let other = [BasisBrdf::Lambert, BasisBrdf::Phong { exponent: 500.0 }];
        assert!(t.beta_in_basis(&other, 2).is_none());
        // A lobe no material uses may be missing; so may an unknown type then.
        let mut diffuse_only = t.clone_without_gloss();
        assert!(diffuse_only
            .beta_in_basis(&[BasisBrdf::Lambert], 2)
            .is_some());
        diffuse_only.lobes[1] = None;
        assert!(diffuse_only
            .beta_in_basis(&[BasisBrdf::Lambert], 2)
            .is_some());
        // Weights of another vertex count: none.
        assert!(t.beta_in_basis(&basis, 3).is_none());
        // The floor's basis: the lobes some material uses, in the truth's order; none when
        // a used lobe is of an unknown type, whatever an unused one is.
        assert_eq!(
            t.used_lobes(),
            Some(vec![
                BasisBrdf::Lambert,
                BasisBrdf::Phong { exponent: 50.0 }
            ])
        );
        assert_eq!(diffuse_only.used_lobes(), Some(vec![BasisBrdf::Lambert]));
        let mut unknown = t.clone_without_gloss();
        unknown.lobes[0] = None;
        assert_eq!(unknown.used_lobes(), None);
    }

    impl TrueMaterials {
        fn clone_without_gloss(&self) -> TrueMaterials {
            TrueMaterials {
                names: self.names.clone(),
                lambert: self.lambert,
                weights: self.weights.clone(),
                lobes: self.lobes.clone(),
                lambda: self.lambda.iter().map(|m| vec![m[0], [0.0; 3]]).collect(),
            }
        }
    }
}
