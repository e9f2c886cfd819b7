//! `run --large-mesh`: three faster settings for meshes of about 50K vertices and more,
//! which a run takes by itself from [`LargeMeshSettings::FROM_VERTICES`] vertices.

use super::RunOptions;

/// Faster settings for meshes of about 50K vertices and more (`run --large-mesh`), each
/// a flag of its own that trades a little accuracy per observation for time:
///
/// - blended lighting rows cut within 1% of their energy, not 0.1%: each row within 10% in
///   `ℓ²` ([`RunOptions::blend_tolerance`]); protocol (b)'s light fits read every row of a
///   half photo, and at 100K vertices a half holds tens of thousands of them, so the cut's
///   errors average out where a small mesh's few hundred rows do not;
/// - 3 extra shadow rays in a texel on a shadow edge, not 4, on one grid of strata with
///   the first ray ([`RunOptions::edge_rays`]);
/// - first shadow rays on every other texel plus the horizon band
///   ([`RunOptions::ray_lattice`] 2).
///
/// What they cost and buy is measured in `bench-results/large-mesh.md`: at 100K vertices
/// × 13 photos the run takes 9% less CPU time than the defaults (224.8 against 247.1 CPU s,
/// both with 3 lighting steps) at a held-out error 1.1% lower; on the real Buddha photos
/// (6.6K vertices) less time at the headline unchanged; on the built-in example's
/// 2.9K-vertex mesh the held-out error under the true light rises 13–16%, which is why a
/// run without `--large-mesh` ([`RunOptions::large_mesh_auto`], the CLI's default) uses
/// them only from [`LargeMeshSettings::FROM_VERTICES`]. (They once included 3 lighting
/// steps instead of 5; 3 is now every run's default, [`crate::solve::options::ALTERNATION_QP_ITERS`].)
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LargeMeshSettings {
    /// [`RunOptions::blend_tolerance`].
    pub blend_tolerance: f64,
    /// [`RunOptions::edge_rays`].
    pub edge_rays: usize,
    /// [`RunOptions::ray_lattice`].
    pub ray_lattice: usize,
}

/// The values of `run --large-mesh` ([`LargeMeshSettings`]).
pub const LARGE_MESH: LargeMeshSettings = LargeMeshSettings {
    blend_tolerance: 1e-2,
    edge_rays: 3,
    ray_lattice: 2,
};

impl LargeMeshSettings {
    /// Mesh size from which a run uses these settings by itself, and from which a run
    /// without them suggests them in a note. Measured at 13 photos
    /// (`bench-results/large-mesh.md`), the held-out error under the true light and of
    /// protocol (b): the 2.9K-vertex example +13–16% and +1%; 30K +0.7% and +2.0%; 50K
    /// −1.4% and +0.3%; 100K −1.4% and −0.9%; 400K +0.4% and +5.8%.
    pub const FROM_VERTICES: usize = 50_000;

    /// What these settings buy, as the report notes state it (`bench-results/large-mesh.md`).
    pub const GAIN: &'static str = "at 100K vertices 9% less time at the same held-out error";

    /// The options a run on a mesh of `vertices` uses: `o` with these settings when
    /// `o.large_mesh_auto` and the mesh has at least [`Self::FROM_VERTICES`] vertices
    /// (`Some`), else `None` (`o` as it is).
    pub fn for_mesh(&self, o: &RunOptions, vertices: usize) -> Option<RunOptions> {
        if !o.large_mesh_auto || vertices < Self::FROM_VERTICES {
            return None;
        }
        let mut sized = o.clone();
        self.apply(&mut sized);
        Some(sized)
    }

    /// Set these three options of `o`, leaving every other one as it is.
    pub fn apply(&self, o: &mut RunOptions) {
        o.blend_tolerance = self.blend_tolerance;
        o.edge_rays = self.edge_rays;
        o.ray_lattice = self.ray_lattice;
    }

    /// These settings as the `run` flags that give them.
    pub fn flags(&self) -> String {
        format!(
            "--blend-tolerance {} --edge-rays {} --ray-lattice {}",
            self.blend_tolerance, self.edge_rays, self.ray_lattice
        )
    }

    /// Whether `o` has all three of these settings.
    pub fn in_effect(&self, o: &RunOptions) -> bool {
        o.blend_tolerance == self.blend_tolerance
            && o.edge_rays == self.edge_rays
            && o.ray_lattice == self.ray_lattice
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `apply` sets the three options and nothing else, each differs from its default (or
    /// the flag would not change it), and `in_effect` needs all three.
    #[test]
    fn large_mesh_settings_set_three_options_and_need_all_three() {
        let default = RunOptions::new("ws".into(), "o".into());
        assert!(!LARGE_MESH.in_effect(&default));
        let mut o = default.clone();
        LARGE_MESH.apply(&mut o);
        assert!(LARGE_MESH.in_effect(&o));
        let resets: [fn(&mut RunOptions, &RunOptions); 3] = [
            |o, d| o.blend_tolerance = d.blend_tolerance,
            |o, d| o.edge_rays = d.edge_rays,
            |o, d| o.ray_lattice = d.ray_lattice,
        ];
        let mut all_reset = o.clone();
        for reset in resets {
            let mut one = o.clone();
            reset(&mut one, &default);
            assert!(
                !LARGE_MESH.in_effect(&one),
                "an option equal to its default"
            );
            reset(&mut all_reset, &default);
        }
        // Debug prints every field, floats to the last bit: nothing else was touched.
        assert_eq!(format!("{all_reset:?}"), format!("{default:?}"));
    }

    /// `for_mesh` changes the options only with `large_mesh_auto` and from
    /// `FROM_VERTICES` vertices, and then as `apply` does.
    #[test]
    fn auto_uses_the_settings_from_the_threshold_on() {
        let from = LargeMeshSettings::FROM_VERTICES;
        let given = RunOptions::new("ws".into(), "o".into());
        assert!(
            LARGE_MESH.for_mesh(&given, 10 * from).is_none(),
            "auto is off"
        );
        let mut auto = given.clone();
        auto.large_mesh_auto = true;
        assert!(LARGE_MESH.for_mesh(&auto, from - 1).is_none());
        for vertices in [from, 10 * from] {
            let sized = LARGE_MESH.for_mesh(&auto, vertices).unwrap();
            let mut want = auto.clone();
            LARGE_MESH.apply(&mut want);
            assert_eq!(format!("{sized:?}"), format!("{want:?}"));
        }
    }
}
