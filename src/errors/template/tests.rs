//! Built-in templates, bases, profiles, orders and bounds.

use super::*;

/// Every template file is built in under its file name, and every built-in one loads.
#[test]
fn every_template_file_is_built_in_and_loads() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("templates");
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    files.sort();
    let mut names: Vec<String> = builtin_names().iter().map(|s| s.to_string()).collect();
    names.sort();
    assert_eq!(files, names);
    for n in builtin_names() {
        let m = load(n).unwrap_or_else(|e| panic!("{n}: {e}"));
        assert_eq!(m.name, n);
        assert!(
            n.chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit())
        );
    }
}

/// `order` must list every stage once: a duplicate would apply a stage twice, a missing
/// quantization would silently drop the saturation.
#[test]
fn order_is_a_permutation() {
    let ok = parse(
        "order = [\"bias\", \"scale_factor\", \"misalignment\", \"noise\", \"quantization\"]\n",
        Path::new("o.toml"),
    );
    assert!(ok.is_ok());
    for bad in [
        "[\"bias\", \"bias\", \"misalignment\", \"noise\", \"quantization\"]",
        "[\"bias\", \"noise\"]",
        "[\"wobble\"]",
    ] {
        let e = parse(&format!("order = {bad}\n"), Path::new("o.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("o.toml") && e.contains("`order`"), "{e}");
    }
}

/// A user file can start from a built-in template and override single keys.
#[test]
fn base_template_with_overrides() {
    let m = parse(
        "base = \"ln200\"\nname = \"mine\"\n[gyro]\nnoise = \"0.1 deg/sqrt(h)\"\n",
        Path::new("mine.toml"),
    )
    .unwrap();
    let base = load("ln200").unwrap();
    assert_eq!(m.name, "mine");
    assert!((m.gyro.noise[0] - 0.1f64.to_radians() / 60.0).abs() < 1e-18);
    assert_eq!(m.gyro.bias_turn_on, base.gyro.bias_turn_on);
    assert_eq!(m.accel, base.accel);
}

/// Physically absurd values are refused with the file, the key, the value as written and
/// the bound, in a short message; so are values that overflow in SI and negative
/// magnitudes.
#[test]
fn absurd_values_are_refused() {
    for (text, key, shows) in [
        (
            "[gyro]\nnoise = \"1e300 deg/sqrt(h)\"\n",
            "`gyro.noise`",
            "`1e300 deg/sqrt(h)`",
        ),
        (
            "[accel]\nbias = [\"0 g\", \"2e6 g\", \"0 g\"]\n",
            "`accel.bias`",
            "`2e6 g`",
        ),
        (
            "[gyro]\nmisalignment = \"30 deg\"\n",
            "`gyro.misalignment`",
            "`30 deg`",
        ),
        (
            "[gyro]\nscale_factor_turn_on = \"150 %\"\n",
            "`gyro.scale_factor_turn_on`",
            "150 %",
        ),
        (
            "[gyro]\nbias_gm = { sigma = \"1 deg/h\", tau = \"1e10 s\" }\n",
            "`gyro.bias_gm`",
            "`1e10 s`",
        ),
        (
            "[gyro]\nquantization = \"2 rad\"\n",
            "`gyro.quantization`",
            "`2 rad`",
        ),
        (
            "[accel]\nrange = \"1e308 g\"\n",
            "`accel.range`",
            "`1e308 g`",
        ),
        (
            "[gyro]\nbias_temperature = [\"0 deg/h/degC\", \"1e9 deg/s/degC^2\"]\n",
            "`gyro.bias_temperature`",
            "coefficient 2",
        ),
        (
            "[gyro]\nnoise = \"-0.1 deg/sqrt(h)\"\n",
            "`gyro.noise`",
            "negative",
        ),
        ("rate_hz = 1e12\n", "`rate_hz`", "(0, 1e7]"),
        (
            "temperature_ref = \"-300 degC\"\n",
            "`temperature_ref`",
            "-273.15",
        ),
    ] {
        let e = parse(text, Path::new("t.toml")).unwrap_err().to_string();
        assert!(
            e.starts_with("t.toml: ") && e.contains(key) && e.contains(shows),
            "{e}"
        );
        assert!(e.len() < 260, "{e}");
    }
    let e = parse(
        "[gyro]\nnoise = \"1e300 deg/sqrt(h)\"\n",
        Path::new("t.toml"),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("at most 3438 deg/sqrt(h) = 1 rad/sqrt(s)"),
        "{e}"
    );
}

/// The bounds leave room for any real IMU: a deliberately poor consumer MEMS part loads.
#[test]
fn poor_consumer_mems_is_within_bounds() {
    let m = parse(
        "[gyro]\nbias = \"5 deg/s\"\nbias_turn_on = \"3 deg/s\"\nnoise = \"0.1 deg/s/sqrt(Hz)\"\n\
         scale_factor_turn_on = \"5 %\"\nmisalignment = \"3 deg\"\ng_sensitivity = \"0.5 deg/s/g\"\n\
         quantization = \"0.1 deg/s\"\nrange = \"4000 deg/s\"\n\
         bias_temperature = [\"0.05 deg/s/degC\"]\n\
         [accel]\nbias = \"200 mg\"\nnoise = \"2 mg/sqrt(Hz)\"\nscale_factor = \"5 %\"\n\
         range = \"400 g\"\nquantization = \"10 mg\"\nsize_effect = [\"5 mm\", \"0 mm\", \
         \"0 mm\", \"0 mm\", \"5 mm\", \"0 mm\", \"0 mm\", \"0 mm\", \"5 mm\"]\n",
        Path::new("mems.toml"),
    );
    assert!(m.is_ok(), "{:?}", m.err());
}

/// `post_filter_noise` is noise added after the output filter: without a filter it would be
/// `noise` under another name, so it is refused there, naming the key; with one it is read.
#[test]
fn post_filter_noise_needs_an_output_filter() {
    let e = parse(
        "[accel]\npost_filter_noise = \"0.1 m/s/sqrt(h)\"\n",
        Path::new("p.toml"),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("p.toml")
            && e.contains("accel.post_filter_noise")
            && e.contains("[output_filter]"),
        "{e}"
    );
    let m = parse(
        "[accel]\npost_filter_noise = [\"0 m/s/sqrt(h)\", \"0 m/s/sqrt(h)\", \"0.6 m/s/sqrt(h)\"]\n\
         [output_filter]\ninternal_rate_hz = 800\nkind = \"moving_average\"\ntaps = 4\n",
        Path::new("p.toml"),
    )
    .unwrap();
    assert_eq!(m.accel.post_filter_noise, [0.0, 0.0, 0.01]);
    assert_eq!(m.gyro.post_filter_noise, [0.0; 3]);
}

/// `quantization_noise` is an angle or a velocity (Q of 3Q²/τ²), one value or three: a rate
/// unit is refused with the key.
#[test]
fn quantization_noise_is_read_as_q() {
    let e = parse(
        "[gyro]\nquantization_noise = \"0.01 deg/s\"\n",
        Path::new("q.toml"),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("q.toml") && e.contains("gyro.quantization_noise") && e.contains("not a rate"),
        "{e}"
    );
    let m = parse(
        "[gyro]\nquantization_noise = [\"1 urad\", \"2 urad\", \"3 urad\"]\n\
         [accel]\nquantization_noise = \"0.5 mm/s\"\nquantization = \"1.2 mm/s\"\n",
        Path::new("q.toml"),
    )
    .unwrap();
    assert_eq!(m.gyro.quantization_noise, [1e-6, 2e-6, 3e-6]);
    assert_eq!(m.accel.quantization_noise, [0.5e-3; 3]);
}
