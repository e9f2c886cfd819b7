//! The truth of a synthetic workspace (`truth/manifest.json`, written by `synth`): per
//! photo the environment map it was rendered with, its exposure and white balance, and
//! which photos are held out.

use crate::sphere::envmap::{LatLong, OctEnv};
use crate::{Error, Result, Vec3};
use nalgebra::Matrix3;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// One photo's entry in `truth/manifest.json`.
#[derive(Debug, Clone)]
pub struct TruthPhoto {
    /// Lat-long map the photo was rendered with (the manifest's entry joined to the
    /// `truth/` folder: a path to open as it is).
    pub env: PathBuf,
    /// Linear exposure factor applied to the rendering.
    pub exposure: f64,
    /// Per-channel white-balance gains.
    pub white_balance: [f64; 3],
    /// Name of the embedded map the photo was rendered under (empty where the manifest
    /// has none).
    pub map: String,
    /// The map's azimuthal rotation in texels: photos with the same map and rotation were
    /// taken under one sky (0 where the manifest has none).
    pub rotation_texels: u64,
    /// The sun direction (the truth's environment frame) of a sun-and-sky map.
    pub sun: Option<Vec3>,
}

/// The ground truth of a synthetic workspace (`truth/manifest.json`, written by `synth`).
#[derive(Debug, Clone)]
pub struct Truth {
    /// The `truth/` folder.
    pub dir: PathBuf,
    /// Held-out photo names.
    pub held_out: Vec<String>,
    /// Rows `e_x, e_y, e_z` of the truth maps' environment frame (world coordinates).
    pub env_from_world: Matrix3<f64>,
    /// Per photo name.
    pub photos: BTreeMap<String, TruthPhoto>,
    /// The frame azimuth of north (the truth's environment frame) of geotagged photos.
    pub north: Option<f64>,
    /// The maps [`Truth::light`] has made, by photo, side and frame: a held-out photo's
    /// light is asked for by the held-out tracker and again by the evaluation.
    lights: Arc<Mutex<HashMap<LightKey, OctEnv>>>,
}

/// A photo name, a map side and the bits of the run's `env_from_world`.
type LightKey = (String, usize, [u64; 9]);

impl Truth {
    /// Read `dir/manifest.json`.
    pub fn read(dir: &Path) -> Result<Truth> {
        let path = dir.join("manifest.json");
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        let json: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| Error::format(&path, format!("line {}", e.line()), e.to_string()))?;
        let bad = |what: &str| Error::format(&path, what.to_string(), "missing or malformed");
        let held_out = json["held_out"]
            .as_array()
            .ok_or_else(|| bad("held_out"))?
            .iter()
            .map(|v| {
                v.as_str()
                    .map(str::to_string)
                    .ok_or_else(|| bad("held_out"))
            })
            .collect::<Result<Vec<_>>>()?;
        let frame = json["env_frame"]
            .as_array()
            .ok_or_else(|| bad("env_frame"))?;
        let mut rows = [[0.0f64; 3]; 3];
        for (r, row) in frame.iter().take(3).enumerate() {
            for c in 0..3 {
                rows[r][c] = row[c].as_f64().ok_or_else(|| bad("env_frame"))?;
            }
        }
        let env_from_world = Matrix3::from_row_slice(&rows.concat());
        let mut photos = BTreeMap::new();
        for p in json["photos"].as_array().ok_or_else(|| bad("photos"))? {
            let name = p["name"].as_str().ok_or_else(|| bad("photos[].name"))?;
            let env = p["env"].as_str().ok_or_else(|| bad("photos[].env"))?;
            let wb = &p["white_balance"];
            photos.insert(
                name.to_string(),
                TruthPhoto {
                    env: dir.join(env),
                    exposure: p["exposure"].as_f64().unwrap_or(1.0),
                    white_balance: [0, 1, 2].map(|c| wb[c].as_f64().unwrap_or(1.0)),
                    map: p["map"].as_str().unwrap_or_default().to_string(),
                    rotation_texels: p["rotation_texels"].as_u64().unwrap_or(0),
                    sun: vec3_of(&p["sun"]),
                },
            );
        }
        Ok(Truth {
            dir: dir.to_path_buf(),
            held_out,
            env_from_world,
            photos,
            north: json["north_radians"].as_f64(),
            lights: Arc::default(),
        })
    }

    /// The light photo `name` was taken under, as this run's model sees it: the truth map
    /// resampled into the run's environment frame (`env_from_world`) on an `n × n`
    /// octahedral map, times the photo's exposure and white balance. `None` when the
    /// manifest does not list the photo. Each map is made once and kept.
    pub fn light(
        &self,
        name: &str,
        n: usize,
        env_from_world: &Matrix3<f64>,
    ) -> Result<Option<OctEnv>> {
        let key = (
            name.to_string(),
            n,
            std::array::from_fn(|i| env_from_world.as_slice()[i].to_bits()),
        );
        // A poisoned lock only means another thread panicked: the maps in it are whole.
        let lock = || self.lights.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(env) = lock().get(&key) {
            return Ok(Some(env.clone()));
        }
        let env = self.make_light(name, n, env_from_world)?;
        if let Some(env) = &env {
            lock().insert(key, env.clone());
        }
        Ok(env)
    }

    /// [`Truth::light`] without the cache.
    fn make_light(
        &self,
        name: &str,
        n: usize,
        env_from_world: &Matrix3<f64>,
    ) -> Result<Option<OctEnv>> {
        let Some(p) = self.photos.get(name) else {
            return Ok(None);
        };
        let (ll, _) = LatLong::read_exr(&p.env)?;
        // Same frame: resample directly (exact energy); otherwise re-express each lat-long
        // pixel's direction in the truth frame and look it up there.
        let same = (env_from_world - self.env_from_world).abs().max() < 1e-9;
        let ll = if same {
            ll
        } else {
            let to_truth = self.env_from_world * env_from_world.transpose();
            let mut out = LatLong::black(ll.height);
            for v in 0..out.height {
                for u in 0..out.width {
                    let d: Vec3 = to_truth * out.dir(u, v);
                    out.rgb[v * out.width + u] = ll.lookup(&d);
                }
            }
            out
        };
        let mut env = OctEnv::from_latlong(&ll, n);
        let s = p.exposure;
        for t in env.rgb.iter_mut() {
            for (v, wb) in t.iter_mut().zip(p.white_balance) {
                *v = (*v as f64 * s * wb) as f32;
            }
        }
        Ok(Some(env))
    }
}

/// A JSON array of three numbers as a vector; `None` for anything else.
fn vec3_of(v: &serde_json::Value) -> Option<Vec3> {
    let a = v.as_array().filter(|a| a.len() == 3)?;
    Some(Vec3::new(a[0].as_f64()?, a[1].as_f64()?, a[2].as_f64()?))
}
