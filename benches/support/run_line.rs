//! The line a benchmark writes above its figures: the date and the command, with the
//! environment variables it was given, that runs it again.

/// The run's date and its environment variables whose names start with one of
/// `prefixes` (sorted), as `Run on DATE as `VARS cargo bench --bench BENCH`.`.
pub fn environment_line(bench: &str, prefixes: &[&str]) -> String {
    let mut vars: Vec<String> = std::env::vars()
        .filter(|(k, _)| prefixes.iter().any(|p| k.starts_with(p)))
        .map(|(k, v)| format!("{k}={}", shell_word(&v)))
        .collect();
    vars.sort();
    format!(
        "Run on {} as `{}cargo bench --bench {bench}`.\n\n",
        super::today::today(),
        vars.iter().map(|v| format!("{v} ")).collect::<String>()
    )
}

/// `v` quoted for a shell when it holds anything but letters, digits and `,._-`.
fn shell_word(v: &str) -> String {
    if !v.is_empty()
        && v.chars()
            .all(|c| c.is_ascii_alphanumeric() || ",._-".contains(c))
    {
        v.to_string()
    } else {
        format!("\"{}\"", v.replace('"', "\\\""))
    }
}
