//! The built-in scenes: their definitions (shape, lighting, materials), geometry (the Spot mesh or generated parts), per-vertex material weights, and the camera and light placement helpers.

use super::*;

/// Geometry of a scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Shape {
    /// Unit icosphere.
    Sphere,
    /// Unit icosphere above a square ground plane (cast shadows).
    SpherePlane,
    /// The Spot mesh, two materials split by a tilted plane with a blended band.
    Spot,
    /// The Spot mesh standing on a square ground plane; on both, the two materials' weights
    /// follow a procedural noise pattern ([`geometry::pattern`]) that SIFT can match.
    SpotTextured,
}

/// How the illumination changes from photo to photo.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Lighting {
    /// One map, unrotated, for every photo.
    Static(&'static str),
    /// One map, a different random azimuthal rotation per photo.
    Rotating(&'static str),
    /// A different map per photo (cycling through the list), each randomly rotated.
    Varying(&'static [&'static str]),
    /// A clear sky per photo from the sun-and-sky model ([`crate::solve::light::sky`]):
    /// the sun at azimuth `2π (i + jitter) / photos` and a random elevation in 20°–60°
    /// ([`super::sky_map`]).
    Sky,
    /// Photos in groups under one sky each: photo `i` sees map `i mod len`, unrotated
    /// (photos taken in sessions round the object; `--light shared`).
    Grouped(&'static [&'static str]),
}

pub(crate) struct SceneDef {
    pub(crate) name: &'static str,
    pub(crate) description: &'static str,
    pub(crate) shape: Shape,
    pub(crate) lobes: Vec<Lobe>,
    /// Per material: name and λ per lobe.
    pub(crate) materials: Vec<(&'static str, Vec<[f64; 3]>)>,
    pub(crate) lighting: Lighting,
    pub(crate) photos: usize,
}

pub(crate) const ALL_MAPS: &[&str] = &data::MAP_NAMES;

pub(crate) fn scene_defs() -> Vec<SceneDef> {
    let phong = |e: f64| Lobe::Phong { exponent: e };
    vec![
        SceneDef {
            name: "sphere-diffuse",
            description: "Lambertian sphere, one real map (known reflectance, unknown light: paper Sec. 6.1)",
            shape: Shape::Sphere,
            lobes: vec![Lobe::Lambert],
            materials: vec![("clay", vec![[0.7, 0.5, 0.3]])],
            lighting: Lighting::Static("courtyard"),
            photos: 8,
        },
        SceneDef {
            name: "sphere-glossy",
            description: "Lambert + Phong 50 sphere, one real map (paper Sec. 6.1)",
            shape: Shape::Sphere,
            lobes: vec![Lobe::Lambert, phong(50.0)],
            materials: vec![("glossy", vec![[0.5, 0.35, 0.2], [0.35, 0.35, 0.35]])],
            lighting: Lighting::Static("courtyard"),
            photos: 8,
        },
        SceneDef {
            name: "sphere-specular",
            description: "Lambert + Phong 500 sphere, one real map (paper Sec. 6.1)",
            shape: Shape::Sphere,
            lobes: vec![Lobe::Lambert, phong(500.0)],
            materials: vec![("specular", vec![[0.5, 0.35, 0.2], [0.35, 0.35, 0.35]])],
            lighting: Lighting::Static("courtyard"),
            photos: 8,
        },
        SceneDef {
            name: "sphere-plane",
            description: "glossy sphere casting shadows on a diffuse plane, the sunny city map rotated per photo",
            shape: Shape::SpherePlane,
            lobes: vec![Lobe::Lambert, phong(50.0)],
            materials: vec![
                ("glossy-sphere", vec![[0.6, 0.3, 0.2], [0.3, 0.3, 0.3]]),
                ("diffuse-plane", vec![[0.5, 0.5, 0.5], [0.0, 0.0, 0.0]]),
            ],
            lighting: Lighting::Rotating("city"),
            photos: 12,
        },
        SceneDef {
            name: "spot-varying",
            description: "Spot, two blended materials, a different real map and rotation per photo, held-out photos",
            shape: Shape::Spot,
            lobes: vec![Lobe::Lambert, phong(50.0), Lobe::Ggx { alpha: 0.3 }],
            materials: vec![
                ("orange-ggx", vec![[0.8, 0.45, 0.2], [0.0, 0.0, 0.0], [0.25, 0.25, 0.25]]),
                ("blue-phong", vec![[0.2, 0.3, 0.6], [0.3, 0.3, 0.3], [0.0, 0.0, 0.0]]),
            ],
            lighting: Lighting::Varying(ALL_MAPS),
            photos: 16,
        },
        SceneDef {
            name: "spot-ggx",
            description: "Spot, two blended materials with lobes the transport resolves (Lambert + GGX 0.3, Lambert), a different real map and rotation per photo, held-out photos",
            shape: Shape::Spot,
            lobes: vec![Lobe::Lambert, Lobe::Ggx { alpha: 0.3 }],
            materials: vec![
                ("orange-ggx", vec![[0.8, 0.45, 0.2], [0.25, 0.25, 0.25]]),
                ("blue-lambert", vec![[0.2, 0.3, 0.6], [0.0, 0.0, 0.0]]),
            ],
            lighting: Lighting::Varying(ALL_MAPS),
            photos: 16,
        },
        SceneDef {
            name: "spot-diffuse",
            description: "Spot, two blended Lambertian materials, a different real map and rotation per photo, held-out photos",
            shape: Shape::Spot,
            lobes: vec![Lobe::Lambert],
            materials: vec![
                ("orange", vec![[0.8, 0.45, 0.2]]),
                ("blue", vec![[0.2, 0.3, 0.6]]),
            ],
            lighting: Lighting::Varying(ALL_MAPS),
            photos: 16,
        },
        SceneDef {
            name: "spot-one",
            description: "Spot, one material (Lambert + GGX 0.3), a different real map and rotation per photo, held-out photos",
            shape: Shape::Spot,
            lobes: vec![Lobe::Lambert, Lobe::Ggx { alpha: 0.3 }],
            materials: vec![("orange-ggx", vec![[0.8, 0.45, 0.2], [0.25, 0.25, 0.25]])],
            lighting: Lighting::Varying(ALL_MAPS),
            photos: 16,
        },
        SceneDef {
            name: "spot-three",
            description: "Spot, three blended materials in bands (Lambert + GGX 0.3, Lambert, Lambert + GGX 0.3), a different real map and rotation per photo, held-out photos",
            shape: Shape::Spot,
            lobes: vec![Lobe::Lambert, Lobe::Ggx { alpha: 0.3 }],
            materials: vec![
                ("orange-ggx", vec![[0.8, 0.45, 0.2], [0.25, 0.25, 0.25]]),
                ("blue-lambert", vec![[0.2, 0.3, 0.6], [0.0, 0.0, 0.0]]),
                ("green-ggx", vec![[0.25, 0.6, 0.3], [0.15, 0.15, 0.15]]),
            ],
            lighting: Lighting::Varying(ALL_MAPS),
            photos: 16,
        },
        SceneDef {
            name: "spot-sky",
            description: "Spot, two blended materials, outdoors: a clear sky (Hosek–Wilkie), sun and ground per photo with a different known sun direction, held-out photos",
            shape: Shape::Spot,
            lobes: vec![Lobe::Lambert, Lobe::Ggx { alpha: 0.3 }],
            materials: vec![
                ("orange-ggx", vec![[0.8, 0.45, 0.2], [0.25, 0.25, 0.25]]),
                ("blue-lambert", vec![[0.2, 0.3, 0.6], [0.0, 0.0, 0.0]]),
            ],
            lighting: Lighting::Sky,
            photos: 16,
        },
        SceneDef {
            name: "spot-static",
            description: "Spot, two blended materials, one real map for every photo (static illumination)",
            shape: Shape::Spot,
            lobes: vec![Lobe::Lambert, phong(50.0), Lobe::Ggx { alpha: 0.3 }],
            materials: vec![
                ("orange-ggx", vec![[0.8, 0.45, 0.2], [0.0, 0.0, 0.0], [0.25, 0.25, 0.25]]),
                ("blue-phong", vec![[0.2, 0.3, 0.6], [0.3, 0.3, 0.3], [0.0, 0.0, 0.0]]),
            ],
            lighting: Lighting::Static("forest"),
            photos: 12,
        },
        SceneDef {
            name: "spot-groups",
            description: "Spot, two blended materials, photos in three groups under one real map each (courtyard, forest, city), held-out photos in every group",
            shape: Shape::Spot,
            lobes: vec![Lobe::Lambert, phong(50.0), Lobe::Ggx { alpha: 0.3 }],
            materials: vec![
                ("orange-ggx", vec![[0.8, 0.45, 0.2], [0.0, 0.0, 0.0], [0.25, 0.25, 0.25]]),
                ("blue-phong", vec![[0.2, 0.3, 0.6], [0.3, 0.3, 0.3], [0.0, 0.0, 0.0]]),
            ],
            lighting: Lighting::Grouped(&["courtyard", "forest", "city"]),
            photos: 16,
        },
        SceneDef {
            name: "spot-textured",
            description: "Spot on a ground plane, two materials in a high-frequency noise pattern (texture for SfM), one real map for every photo, held-out photos",
            shape: Shape::SpotTextured,
            lobes: vec![Lobe::Lambert, phong(50.0), Lobe::Ggx { alpha: 0.3 }],
            materials: vec![
                ("cream-ggx", vec![[0.85, 0.75, 0.55], [0.0, 0.0, 0.0], [0.15, 0.15, 0.15]]),
                ("dark-phong", vec![[0.06, 0.05, 0.05], [0.15, 0.15, 0.15], [0.0, 0.0, 0.0]]),
            ],
            lighting: Lighting::Static("courtyard"),
            photos: 24,
        },
    ]
}

/// The scenes on Spot alone ([`Shape::Spot`]), whose mesh can be refined to an exact
/// vertex count.
pub(crate) fn spot_scene_names() -> Vec<&'static str> {
    scene_defs()
        .iter()
        .filter(|d| d.shape == Shape::Spot)
        .map(|d| d.name)
        .collect()
}

/// The scene names `synth` knows, in a fixed order.
pub fn scene_names() -> Vec<&'static str> {
    scene_defs().iter().map(|d| d.name).collect()
}

/// Embedded map `name`.
pub(crate) fn embedded_map(name: &str) -> Result<LatLong> {
    let bytes: &[u8] = match name {
        "city" => include_bytes!("../../tests/fixtures/synth/hdri/city.exr"),
        "courtyard" => include_bytes!("../../tests/fixtures/synth/hdri/courtyard.exr"),
        "forest" => include_bytes!("../../tests/fixtures/synth/hdri/forest.exr"),
        "interior" => include_bytes!("../../tests/fixtures/synth/hdri/interior.exr"),
        "night" => include_bytes!("../../tests/fixtures/synth/hdri/night.exr"),
        "studio" => include_bytes!("../../tests/fixtures/synth/hdri/studio.exr"),
        "sunrise" => include_bytes!("../../tests/fixtures/synth/hdri/sunrise.exr"),
        "sunset" => include_bytes!("../../tests/fixtures/synth/hdri/sunset.exr"),
        other => return Err(Error::Internal(format!("no embedded map named `{other}`"))),
    };
    LatLong::read_exr_bytes(bytes, &format!("embedded map {name}")).map(|(map, _)| map)
}

pub(crate) const SPOT_PLY: &[u8] = include_bytes!("../../tests/fixtures/synth/spot.ply");

/// The Spot mesh, read by the project's PLY reader from a temporary copy.
pub(crate) fn spot_mesh(out: &Path) -> Result<(Vec<Vec3>, Vec<[u32; 3]>)> {
    let tmp = out.join(".spot-source.ply");
    std::fs::write(&tmp, SPOT_PLY).map_err(|e| Error::io(&tmp, e))?;
    let read = Mesh::read_ply(&tmp);
    std::fs::remove_file(&tmp).map_err(|e| Error::io(&tmp, e))?;
    let (mesh, _) = read?;
    Ok((mesh.positions, mesh.faces))
}

/// Geometry for `shape` with at least `min_vertices` vertices (where the shape allows;
/// exactly that many with `exact`, spot only), and the camera target `(centre, radius)`.
pub(crate) fn make_geometry(
    shape: Shape,
    min_vertices: usize,
    exact: bool,
    out: &Path,
) -> Result<Geometry> {
    if exact && shape != Shape::Spot {
        return Err(Error::Config(format!(
            "an exact vertex count needs a spot scene ({}): the other shapes are built from parts",
            spot_scene_names().join(", ")
        )));
    }
    let sphere_level = |target: usize| -> u32 {
        (0..12)
            .find(|&s| 10 * 4usize.pow(s) + 2 >= target)
            .unwrap_or(11)
    };
    match shape {
        Shape::Sphere => {
            let (p, f) = geometry::icosphere(sphere_level(min_vertices));
            Ok((p, f, Vec3::zeros(), 1.0))
        }
        Shape::SpherePlane => {
            // Sphere ~80% of the vertices, plane the rest.
            let (p, f) = geometry::icosphere(sphere_level(min_vertices * 4 / 5));
            let cells = ((min_vertices as f64 / 5.0).sqrt().ceil() as u32).max(8);
            let (pp, pf) =
                geometry::plane(&Vec3::new(0.0, -PLANE_DROP, 0.0), &Vec3::y(), 6.0, cells);
            let (mut pos, mut faces) = (p, f);
            geometry::append(&mut pos, &mut faces, &pp, &pf);
            Ok((pos, faces, Vec3::new(0.0, -0.4, 0.0), 1.9))
        }
        Shape::Spot => {
            let (mut p, mut f) = spot_mesh(out)?;
            if exact {
                if p.len() > min_vertices {
                    return Err(Error::Config(format!(
                        "an exact vertex count of {min_vertices} is below the spot mesh's own {} vertices",
                        p.len()
                    )));
                }
                (p, f) = geometry::refine_to(&p, &f, min_vertices);
            }
            while p.len() < min_vertices {
                let (q, g) = geometry::subdivide(&p, &f);
                p = q;
                f = g;
            }
            let (lo, hi) = crate::import::mesh::bounding_box(&p);
            let c = (lo + hi) * 0.5;
            let r = p.iter().map(|q| (q - c).norm()).fold(0.0, f64::max);
            Ok((p, f, c, r))
        }
        Shape::SpotTextured => {
            // Spot as above (at least 2/5 of the vertices), on a plane touching its lowest
            // point, 2.5× its largest horizontal extent on a side, the rest of the vertices.
            let (mut p, mut f) = spot_mesh(out)?;
            while p.len() < min_vertices * 2 / 5 {
                let (q, g) = geometry::subdivide(&p, &f);
                p = q;
                f = g;
            }
            let (lo, hi) = crate::import::mesh::bounding_box(&p);
            let c = (lo + hi) * 0.5;
            let r = p.iter().map(|q| (q - c).norm()).fold(0.0, f64::max);
            let side = 2.5 * (hi.x - lo.x).max(hi.z - lo.z);
            let cells = ((min_vertices.saturating_sub(p.len()) as f64).sqrt().ceil() as u32).max(8);
            let (pp, pf) = geometry::plane(&Vec3::new(c.x, lo.y, c.z), &Vec3::y(), side, cells);
            geometry::append(&mut p, &mut f, &pp, &pf);
            Ok((p, f, c, r))
        }
    }
}

/// Positions, faces, camera target centre and radius.
pub(crate) type Geometry = (Vec<Vec3>, Vec<[u32; 3]>, Vec3, f64);

/// Height of the ground plane below the unit sphere's centre (a small gap under it).
pub(crate) const PLANE_DROP: f64 = 1.02;

/// Spacing of the planes between a spot scene's material bands, relative to the bounding
/// box diagonal. Three materials: planes at ±0.07 of the diagonal; Spot's vertices span
/// −0.28 … +0.23 of it along the split direction, so 499, 520 and 421 of its 2,930
/// vertices are pure materials 0, 1 and 2 (the rest are in the blended bands).
pub(crate) const SPOT_BAND_SPACING: f64 = 0.14;

/// Per-vertex material weights (row-major `n × K`).
pub(crate) fn make_weights(shape: Shape, positions: &[Vec3], k: usize) -> Vec<f64> {
    let mut w = vec![0.0; positions.len() * k];
    match shape {
        Shape::Sphere => w.iter_mut().for_each(|x| *x = 1.0),
        Shape::SpherePlane => {
            for (i, p) in positions.iter().enumerate() {
                let m = if p.y < -(1.0 + PLANE_DROP) / 2.0 {
                    1
                } else {
                    0
                };
                w[i * k + m] = 1.0;
            }
        }
        Shape::Spot => {
            // K bands split by K − 1 parallel tilted planes, evenly spaced by
            // SPOT_BAND_SPACING of the diagonal and centred on the box centre (one plane
            // through the centre for two materials); linear blend over a band of 8% of the
            // diagonal at each plane. Material j's weight is s_{j−1} − s_j, s_j the blend
            // across plane j (s_{−1} = 1, s_{K−1} = 0): non-negative, summing to 1.
            let (lo, hi) = crate::import::mesh::bounding_box(positions);
            let c = (lo + hi) * 0.5;
            let diag = (hi - lo).norm();
            let band = 0.08 * diag;
            let dir = Vec3::new(1.0, 0.6, 0.3).normalize();
            let planes: Vec<f64> = (0..k.saturating_sub(1))
                .map(|j| (j as f64 - (k as f64 - 2.0) / 2.0) * SPOT_BAND_SPACING * diag)
                .collect();
            for (i, p) in positions.iter().enumerate() {
                let t = (p - c).dot(&dir);
                let mut prev = 1.0;
                for (j, &tj) in planes.iter().enumerate() {
                    let s = ((t - tj) / band + 0.5).clamp(0.0, 1.0);
                    w[i * k + j] = prev - s;
                    prev = s;
                }
                w[i * k + k - 1] = prev;
            }
        }
        Shape::SpotTextured => {
            // Noise lattice 6% of the object's size (the bounding box of everything above
            // the ground, which is the lowest vertex's height): blobs 3-6 mesh edges across
            // on Spot, 2-4 grid cells on the plane.
            let floor = positions.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
            let above: Vec<Vec3> = positions
                .iter()
                .filter(|p| p.y > floor + 1e-9)
                .copied()
                .collect();
            let (lo, hi) = crate::import::mesh::bounding_box(&above);
            let scale = 0.06 * (hi - lo).norm();
            for (i, p) in positions.iter().enumerate() {
                let s = geometry::pattern(&(p / scale));
                w[i * k] = 1.0 - s;
                w[i * k + 1] = s;
            }
        }
    }
    w
}

/// A pinhole camera at `eye` looking at `target`, image −y along `up`:
/// `z = (target − eye)/|…|`, `x = z × up / |…|` (right), `y = z × x` (down).
pub fn look_at(
    eye: &Vec3,
    target: &Vec3,
    up: &Vec3,
    width: u32,
    height: u32,
    fov_deg: f64,
) -> PinholeCamera {
    let z = (target - eye).normalize();
    let x = z.cross(up).normalize();
    let y = z.cross(&x);
    let r = nalgebra::Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    let f = width.min(height) as f64 / 2.0 / (fov_deg.to_radians() / 2.0).tan();
    PinholeCamera {
        width,
        height,
        fx: f,
        fy: f,
        cx: width as f64 / 2.0,
        cy: height as f64 / 2.0,
        rotation: r,
        translation: -(r * eye),
    }
}

/// `map` turned about `e_z` by `shift` whole texels: what was at azimuth `φ` is now at
/// `φ + 2π shift / W` (exact: no resampling).
pub fn rotate_texels(map: &LatLong, shift: usize) -> LatLong {
    let w = map.width;
    let mut out = map.clone();
    for v in 0..map.height {
        for u in 0..w {
            out.rgb[v * w + (u + shift) % w] = map.rgb[v * w + u];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The corners of the box [−1, 1]³ (centre 0, diagonal 2√3), then `n` points along the
    /// split direction through the centre, inside the box (|t| ≤ 1.2: the direction's
    /// largest component is 0.83).
    fn line(n: usize) -> Vec<Vec3> {
        let dir = Vec3::new(1.0, 0.6, 0.3).normalize();
        let mut p = vec![Vec3::new(-1.0, -1.0, -1.0), Vec3::new(1.0, 1.0, 1.0)];
        p.extend((0..n).map(|i| dir * (-1.2 + 2.4 * i as f64 / (n - 1) as f64)));
        p
    }

    #[test]
    fn spot_two_materials_keep_the_single_centred_plane() {
        // The two-material split as it was written before bands: s = clamp(t/band + ½),
        // w = (1 − s, s), band 8% of the diagonal; the general form must reproduce it
        // exactly (the same operations in the same order).
        let p = line(61);
        let w = make_weights(Shape::Spot, &p, 2);
        let (band, dir) = (0.08 * 12f64.sqrt(), Vec3::new(1.0, 0.6, 0.3).normalize());
        for (i, q) in p.iter().enumerate() {
            let s = (q.dot(&dir) / band + 0.5).clamp(0.0, 1.0);
            assert_eq!([w[2 * i], w[2 * i + 1]], [1.0 - s, s], "vertex {i}");
        }
    }

    #[test]
    fn spot_three_materials_are_ordered_bands_that_sum_to_one() {
        let p = line(301);
        let w = make_weights(Shape::Spot, &p, 3);
        let dir = Vec3::new(1.0, 0.6, 0.3).normalize();
        let (diag, band) = (12f64.sqrt(), 0.08 * 12f64.sqrt());
        let plane = SPOT_BAND_SPACING * diag / 2.0;
        for (i, q) in p.iter().enumerate() {
            let wi = &w[3 * i..3 * i + 3];
            // Exact arithmetic would give 1; the telescoping sum rounds at most twice.
            assert!((wi.iter().sum::<f64>() - 1.0).abs() < 1e-15, "{wi:?}");
            assert!(wi.iter().all(|&v| v >= 0.0), "{wi:?}");
            // Pure material j wherever the point is more than half a band from every plane
            // on its side: below −plane material 0, between the planes 1, above 2.
            let t = q.dot(&dir);
            let pure = if t < -plane - band / 2.0 {
                Some(0)
            } else if t.abs() < plane - band / 2.0 {
                Some(1)
            } else if t > plane + band / 2.0 {
                Some(2)
            } else {
                None
            };
            if let Some(j) = pure {
                assert_eq!(wi[j], 1.0, "point {i} at t = {t}: {wi:?}");
            }
        }
        // Every band is reached by the points of the line (planes at ±0.24, |t| ≤ 1.2).
        for j in 0..3 {
            assert!((0..p.len()).any(|i| w[3 * i + j] == 1.0), "material {j}");
        }
    }
}
