//! The north of a geotagged collection ([`crate::solve::light::sky::clock`]): the frame
//! azimuth `ν` that puts every geotagged photo's clock sun where its observations say,
//! chosen by the `θ` search's error summed over those photos before the photos' lighting
//! steps.

use super::{Rows, SkyLight, REGRID_ITERATIONS};
use crate::solve::light::sky::clock::{north_grid, north_refinement, ClockSun};
use crate::solve::light::sky::search::SearchData;
use crate::solve::light::sky::SunSky;
use crate::solve::problem::{par_largest_first, Problem};
use crate::{Error, Result};

impl SkyLight {
    /// North `ν` from the geotagged photos ([`crate::solve::light::sky::clock`]): through the first
    /// [`REGRID_ITERATIONS`] iterations (and at the first step) the best of the coarse
    /// [`north_grid`] by the summed search error, then refined around it; later steps
    /// refine the previous `ν` only. Each candidate is scored with every photo's previous
    /// turbidity and lobe and its residual fixed.
    pub(super) fn update_north(
        &mut self,
        problem: &Problem,
        beta: &[[f64; 3]],
        outer_iteration: usize,
    ) -> Result<()> {
        if self.north_fixed || self.clock.iter().all(Option::is_none) {
            return Ok(());
        }
        let centre = match self.north {
            Some(n) if outer_iteration > REGRID_ITERATIONS => n,
            _ => self.best_north(problem, beta, &north_grid())?,
        };
        let best = self.best_north(problem, beta, &north_refinement(centre))?;
        self.north = Some(best.rem_euclid(std::f64::consts::TAU));
        Ok(())
    }

    /// The candidate `ν` with the least search error summed over the geotagged photos.
    fn best_north(&self, problem: &Problem, beta: &[[f64; 3]], norths: &[f64]) -> Result<f64> {
        let sizes: Vec<usize> = (0..problem.n_photos)
            .map(|i| match self.clock_sun(i) {
                Some(_) => problem.obs.photo_ranges[i].len(),
                None => 0,
            })
            .collect();
        let profiles: Vec<Result<Vec<f64>>> =
            par_largest_first(&sizes, |i| self.north_profile(problem, beta, i, norths));
        let mut total = vec![0.0; norths.len()];
        for p in profiles {
            total.iter_mut().zip(p?).for_each(|(t, v)| *t += v);
        }
        let k = (0..norths.len())
            .min_by(|&a, &b| total[a].total_cmp(&total[b]))
            .ok_or_else(|| Error::Internal("no candidate north".into()))?;
        Ok(norths[k])
    }

    /// Photo `photo`'s search error at each candidate north (zeros without a geotag).
    fn north_profile(
        &self,
        problem: &Problem,
        beta: &[[f64; 3]],
        photo: usize,
        norths: &[f64],
    ) -> Result<Vec<f64>> {
        let Some(sun) = self.clock_sun(photo) else {
            return Ok(vec![0.0; norths.len()]);
        };
        let rows = Rows::new(problem, photo);
        let sys = self.photo_system(problem, beta, &rows);
        let target = self.search_target(&sys, &rows, photo);
        let search = SearchData::new(&sys, &target);
        let prev = &self.params[photo].theta;
        norths
            .iter()
            .map(|&nu| Ok(search.evaluate(clock_theta(sun, nu, prev))?.sse))
            .collect()
    }
}

/// The `θ` of a geotagged photo: its sun at north `north`, the turbidity and lobe of
/// `prev`.
pub(super) fn clock_theta(sun: ClockSun, north: f64, prev: &SunSky) -> SunSky {
    SunSky::from_angles(
        sun.frame_azimuth(north),
        sun.elevation,
        prev.turbidity,
        prev.kappa,
    )
}
