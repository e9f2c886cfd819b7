//! Dates of the proleptic Gregorian calendar as day numbers from 1970-01-01 (the Unix
//! epoch), both ways: what EXIF dates ([`crate::import::photo::capture_time`],
//! [`crate::import::geotag`]) and the benchmarks' dated figures need, without a date
//! library.

/// Days from 1970-01-01 to the date `y-m-d` of the proleptic Gregorian calendar (the
/// era arithmetic of H. Hinnant, "chrono-compatible low-level date algorithms").
pub fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// The date `(y, m, d)` of day `z` after 1970-01-01 (the inverse of
/// [`days_from_civil`], the same era arithmetic).
pub fn civil_from_days(z: i64) -> (i64, i64, i64) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn civil_days_match_known_dates() {
        // Known day numbers (Unix epoch days): 1970-01-01 = 0, 2000-03-01 = 11017
        // (a leap-century February before it), 2024-02-29 = 19782, 1969-12-31 = -1.
        assert_eq!(days_from_civil(1970, 1, 1), 0);
        assert_eq!(days_from_civil(2000, 3, 1), 11017);
        assert_eq!(days_from_civil(2024, 2, 29), 19782);
        assert_eq!(days_from_civil(1969, 12, 31), -1);
    }

    #[test]
    fn civil_dates_round_trip() {
        // Known days (civil_days_match_known_dates) and a span of
        // 1,000 years either side of 1970 map back to themselves.
        assert_eq!(civil_from_days(19_782), (2024, 2, 29));
        assert_eq!(civil_from_days(-1), (1969, 12, 31));
        for z in (-365_000..365_000).step_by(997) {
            let (y, m, d) = civil_from_days(z);
            assert_eq!(days_from_civil(y, m, d), z);
        }
    }
}
