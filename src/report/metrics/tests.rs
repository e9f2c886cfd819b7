use super::*;

fn json_f64s(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

#[test]
fn psnr_of_a_known_mse() {
    // Values in sRGB's linear segment (≤ 0.0031308 encodes as 12.92 v): the pair
    // y = (a + e, a − e) against ŷ = (a, a) has s_c = Σyŷ/Σŷ² = 1 exactly, so both
    // MSEs are (12.92 e)² (PSNR-H: the brightness factor is 12.92 too) and
    // PSNR = −20 log₁₀(12.92 e). f32 inputs: 1e-4 dB.
    let (a, e) = (0.002f32, 0.001f32);
    let gt = vec![[a + e; 3], [a - e; 3]];
    let pred = vec![[a; 3]; 2];
    let mask = vec![true; 2];
    let m = image_metrics(&gt, &pred, 2, 1, &mask);
    let want = -20.0 * (12.92 * e as f64).log10();
    for s in m.scale {
        assert!((s - 1.0).abs() < 1e-6, "{m:?}");
    }
    assert!((m.psnr_l - want).abs() < 1e-4, "{} vs {want}", m.psnr_l);
    assert!((m.psnr_h - want).abs() < 1e-4, "{} vs {want}", m.psnr_h);
    // PSNR-H clips at 4: a photo of 1 (brightness factor 1) against 6 is an error of 3
    // (not 5): −10 log₁₀ 9. The factor is srgb(1) = 1.055 − 0.055 in f32, 1 to
    // ~1e-7, which moves the PSNR by ~1e-6 dB: 1e-5.
    let h = psnr_h(&[[1.0; 3]], &[[6.0; 3]], &[true]);
    assert!((h + 10.0 * 9f64.log10()).abs() < 1e-5, "{h}");
    // PSNR-L clips at 1: 1 against 6 is no error at all.
    assert_eq!(psnr_l(&[[1.0; 3]], &[[6.0; 3]], &[true]), f64::INFINITY);
    assert!((psnr_from_mse(0.01) - 20.0).abs() < 1e-12);
}

#[test]
fn per_channel_scale_removes_a_colour_cast() {
    // ŷ = y / (2, 3, 4): the scales are exactly (2, 3, 4) and the scaled prediction is
    // the photo (PSNR +∞, SSIM 1). Pixels off the mask are ignored however wrong.
    let gt: Vec<[f32; 3]> = (0..64)
        .map(|i| [0.1 + 0.01 * i as f32, 0.5, 0.9 - 0.01 * i as f32])
        .collect();
    let mut pred: Vec<[f32; 3]> = gt
        .iter()
        .map(|p| [p[0] / 2.0, p[1] / 3.0, p[2] / 4.0])
        .collect();
    let mut mask = vec![true; 64];
    pred[5] = [9.0; 3];
    mask[5] = false;
    let m = image_metrics(&gt, &pred, 8, 8, &mask);
    for (s, want) in m.scale.iter().zip([2.0, 3.0, 4.0]) {
        assert!((s - want).abs() < 1e-5, "{m:?}");
    }
    // f32 rounding of ŷ·s leaves ~1e-8 errors: PSNR above 100 dB.
    assert!(m.psnr_h > 100.0 && m.psnr_l > 100.0, "{m:?}");
    assert!((m.ssim - 1.0).abs() < 1e-9, "{m:?}");
    assert_eq!(m.pixels, 63);
}

#[test]
fn ssim_of_identical_images_is_one_and_of_an_offset_matches_the_closed_form() {
    let (w, h) = (17, 13);
    let img: Vec<[f64; 3]> = (0..w * h)
        .map(|i| [0, 1, 2].map(|c| ((i * 7 + c * 5) % 11) as f64 / 10.0))
        .collect();
    let mask: Vec<bool> = (0..w * h).map(|i| (i % w) > 3 && (i / w) > 2).collect();
    assert!((ssim_masked(&img, &img, w, h, &mask) - 1.0).abs() < 1e-12);
    // Constant images c and c + d: every local mean is the constant and every variance
    // and covariance 0, so S = (2c(c + d) + C1) / (c² + (c + d)² + C1) at every pixel.
    let (c, d) = (0.4, 0.15);
    let a = vec![c; w * h];
    let b = vec![c + d; w * h];
    let c1 = SSIM_K1 * SSIM_K1;
    let want = (2.0 * c * (c + d) + c1) / (c * c + (c + d) * (c + d) + c1);
    for s in ssim_map(&a, &b, w, h) {
        // Filter sums of 121 weights: 1e-12.
        assert!((s - want).abs() < 1e-12, "{s} vs {want}");
    }
    let (ai, bi): (Vec<[f64; 3]>, Vec<[f64; 3]>) = (vec![[c; 3]; w * h], vec![[c + d; 3]; w * h]);
    let all = vec![true; w * h];
    assert!((ssim_masked(&ai, &bi, w, h, &all) - want).abs() < 1e-12);
}

#[test]
fn ssim_matches_scikit_image() {
    // Reference values and the script that made them: scripts/ssim_reference.py.
    // Both sides are float64 over the same inputs; only the summation order of the
    // 11-tap filters differs, so 1e-9 is rounding with a wide margin.
    let r: serde_json::Value = serde_json::from_str(include_str!(
        "../../../tests/fixtures/metrics/ssim_reference.json"
    ))
    .unwrap();
    let g = &r["grey"];
    let (w, h) = (
        g["width"].as_u64().unwrap() as usize,
        g["height"].as_u64().unwrap() as usize,
    );
    let map = ssim_map(&json_f64s(&g["a"]), &json_f64s(&g["b"]), w, h);
    let want = json_f64s(&g["map"]);
    assert_eq!(map.len(), want.len());
    for (i, (s, t)) in map.iter().zip(&want).enumerate() {
        assert!((s - t).abs() < 1e-9, "pixel {i}: {s} vs scikit-image {t}");
    }
    // scikit-image's mean leaves out a 5-pixel border.
    let interior = |w: usize, h: usize| -> Vec<bool> {
        (0..w * h)
            .map(|i| (5..w - 5).contains(&(i % w)) && (5..h - 5).contains(&(i / w)))
            .collect()
    };
    let inside = interior(w, h);
    let mean: f64 = map
        .iter()
        .zip(&inside)
        .filter(|(_, &m)| m)
        .map(|(s, _)| s)
        .sum::<f64>()
        / inside.iter().filter(|&&m| m).count() as f64;
    assert!((mean - g["mean"].as_f64().unwrap()).abs() < 1e-9);

    // RGB: the mean of the three channels' means.
    let c = &r["rgb"];
    let (w, h) = (
        c["width"].as_u64().unwrap() as usize,
        c["height"].as_u64().unwrap() as usize,
    );
    let (a, b) = (json_f64s(&c["a"]), json_f64s(&c["b"]));
    let inside = interior(w, h);
    let mut total = 0.0;
    for ch in 0..3 {
        let pick = |v: &[f64]| -> Vec<f64> { v.iter().skip(ch).step_by(3).copied().collect() };
        let map = ssim_map(&pick(&a), &pick(&b), w, h);
        let s: f64 = map
            .iter()
            .zip(&inside)
            .filter(|(_, &m)| m)
            .map(|(s, _)| s)
            .sum();
        total += s / inside.iter().filter(|&&m| m).count() as f64;
    }
    assert!((total / 3.0 - c["mean"].as_f64().unwrap()).abs() < 1e-9);
}

#[test]
fn gaussian_filter_equals_the_mirrored_convolution_by_definition() {
    // The direct definition, every tap through `mirror`, rows then columns, on an image
    // with an interior (17 × 13 > 2r + 1) and a thin one (all border, 4 × 3). The fast
    // interior path adds the same products in the same order: equal to the last bit.
    let k = ssim_kernel();
    let r = SSIM_RADIUS as isize;
    for (w, h) in [(17usize, 13usize), (4, 3)] {
        let img: Vec<f64> = (0..w * h).map(|i| ((i * 37 % 101) as f64).sin()).collect();
        let conv = |get: &dyn Fn(usize, usize) -> f64, horizontal: bool| -> Vec<f64> {
            let mut out = vec![0.0; w * h];
            for y in 0..h {
                for x in 0..w {
                    let mut acc = 0.0;
                    for d in -r..=r {
                        let (xx, yy) = if horizontal {
                            (mirror(x as isize + d, w), y)
                        } else {
                            (x, mirror(y as isize + d, h))
                        };
                        acc += k[(d + r) as usize] * get(xx, yy);
                    }
                    out[y * w + x] = acc;
                }
            }
            out
        };
        let rows = conv(&|x, y| img[y * w + x], true);
        let want = conv(&|x, y| rows[y * w + x], false);
        assert_eq!(gaussian_filter(&img, w, h), want, "{w} × {h}");
    }
}

#[test]
fn ssim_on_the_bounding_box_equals_the_full_image_map_over_the_mask() {
    // The crop is an optimisation only: the full-image map of the zero-outside-mask
    // images, averaged over the mask, is the same number (to rounding, 1e-12).
    let (w, h) = (40, 30);
    let a: Vec<[f64; 3]> = (0..w * h)
        .map(|i| [0, 1, 2].map(|c| ((i * 13 + c * 7) % 17) as f64 / 16.0))
        .collect();
    let b: Vec<[f64; 3]> = a
        .iter()
        .map(|p| p.map(|v| (0.7 * v + 0.2).min(1.0)))
        .collect();
    let mask: Vec<bool> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            (x - 22.0).powi(2) + (y - 14.0).powi(2) < 64.0
        })
        .collect();
    let got = ssim_masked(&a, &b, w, h, &mask);
    let mut sum = 0.0;
    for c in 0..3 {
        let zero = |img: &[[f64; 3]]| -> Vec<f64> {
            img.iter()
                .zip(&mask)
                .map(|(p, &m)| if m { p[c] } else { 0.0 })
                .collect()
        };
        let map = ssim_map(&zero(&a), &zero(&b), w, h);
        sum += map
            .iter()
            .zip(&mask)
            .filter(|(_, &m)| m)
            .map(|(s, _)| s)
            .sum::<f64>();
    }
    let want = sum / (3 * mask.iter().filter(|&&m| m).count()) as f64;
    assert!((got - want).abs() < 1e-12, "{got} vs {want}");
    assert!(got < 0.99, "a real difference scores below 1: {got}");
    assert!(ssim_masked(&a, &b, w, h, &vec![false; w * h]).is_nan());
}

#[test]
fn rmse_after_channel_scale_and_headline_by_hand() {
    // y = (1, 3) in every channel, ŷ = (1, 1): s = 4/2 = 2, residuals (−1, 1), RMSE 1;
    // RMS of y = √5.
    let gt = vec![[1.0f32; 3], [3.0; 3]];
    let pred = vec![[1.0f32; 3]; 2];
    let (rmse, rms, s) = rmse_after_channel_scale(&gt, &pred, &[true, true]);
    assert!((rmse - 1.0).abs() < 1e-12 && (rms - 5f64.sqrt()).abs() < 1e-12);
    assert_eq!(s, [2.0; 3]);
    let h = Headline::from_pairs(&[(0.1, 0.2), (0.3, 0.2), (f64::NAN, 1.0)]).unwrap();
    assert_eq!(h.photos, 2);
    assert!((h.ratio - 1.0).abs() < 1e-12 && (h.method_rmse - 0.2).abs() < 1e-12);
    assert!(Headline::from_pairs(&[]).is_none());
}
