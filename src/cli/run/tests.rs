//! `run`'s flags against the library's defaults, `--help`, and the flag tables of
//! `docs/flags.md` and the README.

use crate::{Cli, Command};
use clap::Parser;

/// `run`'s flags repeat most defaults as literals beside `RunOptions::new`: parsing a
/// bare `run WS --out OUT` must give the library's defaults, but for the two the CLI
/// sets on purpose (`--adaptive on`, and the large-mesh settings and the light model by
/// mesh size; the library's defaults are the full model and the options as given).
#[test]
fn bare_run_flags_give_the_library_defaults() {
    let cli = Cli::try_parse_from(["relight-cpc", "run", "ws", "--out", "o"]).unwrap();
    let Command::Run(args) = cli.command else {
        panic!("`run` parsed as another subcommand");
    };
    let got = args.options().unwrap();
    let mut want = relight_cpc::run::RunOptions::new("ws".into(), "o".into());
    assert!(!want.adaptive, "the library's default is the full model");
    want.adaptive = true;
    assert!(
        !want.large_mesh_auto,
        "the library's default is the options as given"
    );
    want.large_mesh_auto = true;
    assert!(
        !want.light_by_scene,
        "the library's default is the light as given"
    );
    want.light_by_scene = true;
    // Debug prints every field, floats to the last bit, so this is exact equality.
    assert_eq!(format!("{got:?}"), format!("{want:?}"));
}

/// `--large-mesh` means exactly the three flags its help names and refuses to be
/// combined with any of them (the user would not know which value won); without it
/// the run chooses by mesh size unless one of them or `--no-large-mesh` is given.
#[test]
fn large_mesh_means_the_flags_its_help_names() {
    use clap::CommandFactory;
    let cli = Cli::command();
    let run = cli.find_subcommand("run").unwrap();
    let help = run
        .get_arguments()
        .find(|a| a.get_long() == Some("large-mesh"))
        .and_then(|a| a.get_help())
        .unwrap()
        .to_string();
    // The help lists the flags after "and more:" up to the parenthesis.
    let named = help
        .split("more: ")
        .nth(1)
        .unwrap()
        .split(" (")
        .next()
        .unwrap();
    let flags: Vec<&str> = named.split_whitespace().collect();
    assert_eq!(flags.len(), 6, "three flags with values in {help:?}");
    let parse = |extra: &[&str]| {
        let base = ["relight-cpc", "run", "ws", "--out", "o"];
        Cli::try_parse_from(base.iter().chain(extra).copied())
    };
    let options = |extra: &[&str]| {
        let Command::Run(args) = parse(extra).unwrap().command else {
            panic!("`run` parsed as another subcommand");
        };
        args.options().unwrap()
    };
    let on = options(&["--large-mesh"]);
    assert_eq!(format!("{on:?}"), format!("{:?}", options(&flags)));
    assert!(!on.large_mesh_auto);
    let bare = options(&[]);
    assert!(bare.large_mesh_auto, "chosen by mesh size by default");
    assert!(!relight_cpc::run::LARGE_MESH.in_effect(&bare));
    let mut off = options(&["--no-large-mesh"]);
    assert!(!off.large_mesh_auto);
    off.large_mesh_auto = true;
    assert_eq!(
        format!("{off:?}"),
        format!("{bare:?}"),
        "nothing else changes"
    );
    let conflict = |extra: &[&str]| {
        let err = parse(extra).err().expect("a conflict");
        assert_eq!(
            err.kind(),
            clap::error::ErrorKind::ArgumentConflict,
            "{extra:?}"
        );
    };
    conflict(&["--large-mesh", "--no-large-mesh"]);
    // The lighting step cap is every run's choice, not one of the settings.
    assert!(options(&["--lighting-qp-iterations", "5"]).large_mesh_auto);
    for pair in flags.chunks(2) {
        conflict(&["--large-mesh", pair[0], pair[1]]);
        assert!(
            !options(pair).large_mesh_auto,
            "{pair:?} is the user's choice"
        );
    }
}

/// `run --help` groups its flags under the six headings, in plain words: none of the
/// solver's jargon appears, and every flag with a default shows it.
#[test]
fn run_help_is_grouped_and_plain() {
    use clap::CommandFactory;
    let mut cli = Cli::command();
    let run = cli.find_subcommand_mut("run").unwrap();
    let help = run.render_long_help().to_string();
    for h in [
        "Input",
        "Model",
        "Solver",
        "Evaluation",
        "Output",
        "Performance",
    ] {
        assert!(help.contains(&format!("{h}:")), "no heading {h}:\n{help}");
    }
    for jargon in ["GPCG", "KKT", "IRLS", "MAD", "QP"] {
        let words = help.split(|c: char| !c.is_ascii_alphanumeric());
        assert!(!words.into_iter().any(|w| w == jargon), "{jargon} in help");
    }
    for arg in run.get_arguments() {
        // Switches (--force, ...) have the default `false`, which clap does not show.
        let switch = !arg.get_action().takes_values();
        if arg.get_default_values().len() == 1 && !arg.is_hide_default_value_set() && !switch {
            let d = arg.get_default_values()[0].to_string_lossy().into_owned();
            assert!(
                help.contains(&format!("[default: {d}]")),
                "--{:?}",
                arg.get_long()
            );
        }
    }
}

/// The flags a flag table names (`| \`--a N\`, \`--b T\` | 8, 1e-3 | ...`), each with
/// its stated default: a row's flags and its defaults pair up in order.
fn flag_rows(text: &str) -> Vec<(String, Vec<String>)> {
    let mut rows = Vec::new();
    for row in text.lines().filter(|l| l.starts_with("| `--")) {
        let cells: Vec<&str> = row.split(" | ").collect();
        let flags: Vec<String> = cells[0]
            .split("`--")
            .skip(1)
            .map(|f| f.split([' ', '`']).next().unwrap().to_string())
            .collect();
        let values: Vec<String> = cells[1]
            .split(", ")
            .map(|v| v.trim_matches('`').to_string())
            .collect();
        for (i, flag) in flags.iter().enumerate() {
            let value = (values.len() == flags.len()).then(|| values[i].clone());
            rows.push((flag.clone(), value.into_iter().collect()));
        }
    }
    rows
}

/// Checks every row of a flag table against clap: the flag exists in `run`, and where
/// clap applies a default the row states it. Returns the flags named.
fn check_flag_table(doc: &str, text: &str) -> std::collections::BTreeSet<String> {
    use clap::CommandFactory;
    let cli = Cli::command();
    let run = cli.find_subcommand("run").unwrap();
    let same = |doc: &str, clap: &str| match (doc.parse::<f64>(), clap.parse::<f64>()) {
        (Ok(a), Ok(b)) => a == b,
        _ => doc == clap,
    };
    let mut named = std::collections::BTreeSet::new();
    for (flag, value) in flag_rows(text) {
        let arg = run
            .get_arguments()
            .find(|a| a.get_long() == Some(flag.as_str()))
            .unwrap_or_else(|| panic!("{doc} names --{flag}, which `run` does not have"));
        let d = arg.get_default_values();
        if d.len() == 1 {
            let clap = d[0].to_string_lossy();
            let value = value.first().unwrap_or_else(|| {
                panic!("{doc}: the row of --{flag} does not pair flags with defaults")
            });
            assert!(
                same(value, &clap),
                "{doc} gives --{flag} the default `{value}`, clap `{clap}`"
            );
        }
        named.insert(flag);
    }
    named
}

/// docs/flags.md names every flag of `run` and states each default clap applies; the
/// README's shorter table states the same defaults for the flags it names.
#[test]
fn flag_tables_state_the_cli_defaults() {
    use clap::CommandFactory;
    let cli = Cli::command();
    let run = cli.find_subcommand("run").unwrap();
    let all: std::collections::BTreeSet<String> = run
        .get_arguments()
        .filter_map(|a| a.get_long())
        .filter(|l| *l != "help")
        .map(str::to_string)
        .collect();
    let documented = check_flag_table("docs/flags.md", include_str!("../../../docs/flags.md"));
    let missing: Vec<_> = all.difference(&documented).collect();
    assert!(missing.is_empty(), "docs/flags.md lacks {missing:?}");
    let readme = check_flag_table("README.md", include_str!("../../../README.md"));
    // The README keeps a short table of the flags a user tunes first; fewer than 8
    // means its table was lost or mangled (it has 12 today).
    assert!(readme.len() >= 8, "README names only {readme:?}");
}

/// Without `--light` the run chooses the light model by mesh size; any `--light` value,
/// `paper` included, is the user's choice and is kept at every size.
#[test]
fn a_given_light_model_is_kept_and_none_is_chosen_by_size() {
    use relight_cpc::solve::light::choose::LightChoice;
    let options = |extra: &[&str]| {
        let base = ["relight-cpc", "run", "ws", "--out", "o"];
        let cli = Cli::try_parse_from(base.iter().chain(extra).copied()).unwrap();
        let Command::Run(args) = cli.command else {
            panic!("`run` parsed as another subcommand");
        };
        args.options().unwrap()
    };
    assert!(options(&[]).light_by_scene);
    for (flag, want) in [
        ("paper", LightChoice::Paper),
        ("prior", LightChoice::Prior),
        ("auto", LightChoice::Auto),
        ("constrained", LightChoice::Constrained),
    ] {
        let o = options(&["--light", flag]);
        assert!(!o.light_by_scene, "--light {flag} is the user's choice");
        assert_eq!(o.light, want);
        let basis = [relight_cpc::transport::brdf::BasisBrdf::Lambert];
        let shape = relight_cpc::run::FitShape {
            vertices: 10_000_000,
            basis: &basis,
            photos: 100,
            materials: Some(2),
        };
        let sized = relight_cpc::run::scene_light(&o, shape);
        assert!(sized.is_none(), "--light {flag} kept on a large mesh");
    }
}
