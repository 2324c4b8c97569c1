//! The values options take, checked while clap parses the command line: a
//! value outside its range is a usage error (exit 2, like an unknown
//! option) whose message names the option and the range, before any work
//! starts and before anything is written. The libraries check the same
//! ranges again for the run files and Python, which reach them without
//! clap.

/// A whole number in `lo..=hi` (`hi` = `None`: no upper bound), e.g.
/// `--episodes` (at least 1) or `--replicates` (2 to 64). `-1` and `x` are
/// refused with the range too, not with Rust's parse error.
pub fn whole<T>(
    lo: u64,
    hi: Option<u64>,
) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync + 'static
where
    T: TryFrom<u64> + Clone + Send + Sync + 'static,
{
    move |s: &str| {
        let range = match hi {
            Some(hi) => format!("a whole number from {lo} to {hi}"),
            None => format!("a whole number ≥ {lo}"),
        };
        let v: u64 = s
            .trim()
            .parse()
            .map_err(|_| format!("must be {range}, got {s}"))?;
        if v < lo || hi.is_some_and(|hi| v > hi) {
            return Err(format!("must be {range}, got {v}"));
        }
        T::try_from(v).map_err(|_| format!("must be {range}, got {v}"))
    }
}

/// A number `x`, finite, with `ok(x)`; else "must be `what`, got …".
fn real(s: &str, what: &str, ok: impl Fn(f64) -> bool) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && ok(v) => Ok(v),
        Ok(v) => Err(format!("must be {what}, got {v}")),
        Err(_) => Err(format!("must be {what}, got {s}")),
    }
}

/// A finite number ≥ 0 (`--delta`, `--max-energy`).
pub fn non_negative(s: &str) -> Result<f64, String> {
    real(s, "a finite number ≥ 0", |v| v >= 0.0)
}

/// A finite number > 0 (a tolerance, a distance).
pub fn positive(s: &str) -> Result<f64, String> {
    real(s, "a finite number > 0", |v| v > 0.0)
}

/// A level or rate strictly between 0 and 1 (`--merge`, a false discovery
/// rate).
pub fn open_unit(s: &str) -> Result<f64, String> {
    real(s, "a number in (0, 1), both ends excluded", |v| {
        v > 0.0 && v < 1.0
    })
}

/// A positive number of seconds (`--deadline`, `--join-timeout`).
pub fn seconds(s: &str) -> Result<f64, String> {
    real(s, "a number of seconds > 0", |v| v > 0.0)
}

/// The probability that an attempt is lost (`--loss`): in [0, 1).
pub fn loss(s: &str) -> Result<f64, String> {
    real(s, "a probability in [0, 1)", |v| (0.0..1.0).contains(&v))
}

/// A mean burst length in steps (`--burst`): ≥ 1.
pub fn burst(s: &str) -> Result<f64, String> {
    real(s, "a number of steps ≥ 1", |v| v >= 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_numbers_say_their_range() {
        let episodes = whole::<u64>(1, None);
        assert_eq!(episodes("3"), Ok(3));
        assert_eq!(
            episodes("0"),
            Err("must be a whole number ≥ 1, got 0".into())
        );
        assert_eq!(
            episodes("-1"),
            Err("must be a whole number ≥ 1, got -1".into())
        );
        let replicates = whole::<u32>(2, Some(64));
        assert_eq!(replicates("64"), Ok(64));
        assert_eq!(
            replicates("65"),
            Err("must be a whole number from 2 to 64, got 65".into())
        );
        // A value the type cannot hold is out of the range too.
        assert!(whole::<u8>(0, None)("300").is_err());
    }

    #[test]
    fn reals_say_their_range() {
        assert_eq!(loss("0"), Ok(0.0));
        assert!(loss("1").is_err_and(|e| e.contains("[0, 1)")));
        assert!(burst("0.5").is_err_and(|e| e.contains("≥ 1")));
        assert!(seconds("0").is_err_and(|e| e.contains("> 0")));
        assert!(non_negative("nan").is_err());
        assert!(open_unit("1").is_err() && open_unit("0").is_err() && open_unit("0.05").is_ok());
        assert!(positive("0").is_err_and(|e| e.contains("> 0")));
        assert!(non_negative("-1").is_err_and(|e| e.contains("got -1")));
    }
}
