use super::*;

/// The sun's energy `R · 2π(1 − cos 1°)` is exact on fine and coarse lat-long grids
/// (integral of the map, a sum of pixel radiance × solid angle; f32 storage → 1e-5).
#[test]
fn sun_energy_exact() {
    for h in [16, 64, 512] {
        let mut ll = LatLong::black(h);
        let sun = Sun {
            dir: Vec3::new(0.3, 0.5, 0.8),
            radiance: [1000.0, 500.0, 10.0],
        };
        add_sun(&mut ll, &sun).unwrap();
        let omega = 2.0 * std::f64::consts::PI * (1.0 - SUN_RADIUS_DEG.to_radians().cos());
        let e = ll.integral();
        for (c, (&got, &r)) in e.iter().zip(&sun.radiance).enumerate() {
            let want = r * omega;
            assert!(
                ((got - want) / want).abs() < 1e-5,
                "h={h} c={c}: {got} vs {want}"
            );
        }
    }
}
