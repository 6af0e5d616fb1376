//! Tests of the configuration: defaults, round trip, rejection of bad values.

use super::*;

#[test]
fn default_equals_the_embedded_file() {
    let parsed = Config::from_toml_str(Config::default_toml()).unwrap();
    assert_eq!(parsed, Config::default());
    Config::default().validate().unwrap();
}

#[test]
fn empty_file_is_the_default() {
    assert_eq!(Config::from_toml_str("").unwrap(), Config::default());
}

#[test]
fn toml_round_trip_is_exact() {
    let mut c = Config::default();
    c.test.wall_mu = Some(0.7);
    c.test.sigma3 = Pressure(1e6 * (0.1 + 0.2)); // not exactly representable in decimal
    c.solver.dt = Duration(1.0 / 3.0 * 1e-3);
    c.solver.method = Method::Jacobi;
    c.sample.seed = i64::MAX as u64;
    for cfg in [Config::default(), c] {
        let text = cfg.to_toml_string().unwrap();
        assert_eq!(Config::from_toml_str(&text).unwrap(), cfg, "{text}");
        let json = serde_json::to_string(&cfg).unwrap();
        assert_eq!(serde_json::from_str::<Config>(&json).unwrap(), cfg);
    }
}

#[test]
fn units_are_read_in_the_file() {
    let c = Config::from_toml_str(
        "[test]\nsigma3 = \"500 kPa\"\naxial_velocity = \"0.5 m/s\"\nstrip_thickness = \"7.5 m\"\n",
    )
    .unwrap();
    assert_eq!(c.test.sigma3, Pressure(5e5));
    assert_eq!(c.test.axial_velocity, Velocity(0.5));
    assert_eq!(c.test.strip_thickness, Length(7.5));
    let e = Config::from_toml_str("[test]\nsigma3 = \"8 m\"\n").unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("MPa") && msg.contains("line 2"), "{msg}");
}

#[test]
fn unknown_keys_and_sections_are_rejected() {
    for text in [
        "[test]\nsigma_3 = 8e6\n",
        "[tests]\nmu = 0.3\n",
        "disks = 10\n",
        "[solver]\nmethod = \"sor\"\n",
    ] {
        let e = Config::from_toml_str(text).unwrap_err();
        assert!(matches!(e, Error::Parse { line: 1 | 2, .. }), "{text}: {e}");
    }
}

#[test]
fn each_bad_value_is_rejected_naming_its_field() {
    let cases: &[(&str, &str)] = &[
        ("[sample]\ndisks = 49", "sample.disks"),
        ("[sample]\nr_min = 0", "sample.r_min"),
        ("[sample]\nr_min = -1", "sample.r_min"),
        ("[sample]\nr_max = \"0.4 m\"", "sample.r_max"),
        ("[sample]\nr_max = nan", "sample.r_max"),
        ("[sample]\ndensity = 0", "sample.density"),
        ("[sample]\naspect_ratio = 0", "sample.aspect_ratio"),
        ("[sample]\naspect_ratio = nan", "sample.aspect_ratio"),
        // Values config --check accepted and a run then failed on without naming the key
        // (issue 36, item 12).
        ("[sample]\naspect_ratio = 1e-320", "sample.aspect_ratio"),
        ("[sample]\ndensity = \"1e308 kg/m3\"", "sample.density"),
        ("[sample]\ndensity = \"1e-320 kg/m3\"", "sample.density"),
        ("[test]\naxial_velocity = \"1e308 m/s\"", "test.axial_velocity"),
        ("[test]\naxial_velocity = \"1e-320 m/s\"", "test.axial_velocity"),
        ("[solver]\ndt = 0", "solver.dt"),
        ("[solver]\ndt = inf", "solver.dt"),
        // Absurd for a time step; 1e-320 s used to be blamed on solver.velocity_tol (which
        // is derived from r_min / dt and overflowed).
        ("[solver]\ndt = \"1e-320 s\"", "solver.dt"),
        ("[solver]\ndt = \"1e-10 s\"", "solver.dt"),
        ("[solver]\ndt = \"2 s\"", "solver.dt"),
        ("[solver]\ntheta = 0.4", "solver.theta"),
        ("[solver]\ntheta = 1.1", "solver.theta"),
        ("[solver]\ntol = 0", "solver.tol"),
        ("[solver]\nmax_iter = 0", "solver.max_iter"),
        ("[solver]\njacobi_relax = 0", "solver.jacobi_relax"),
        ("[solver]\nalert_distance = -0.1", "solver.alert_distance"),
        ("[solver]\noverlap_limit = 0", "solver.overlap_limit"),
        ("[solver]\ndeep_overlap = -0.001", "solver.deep_overlap"),
        ("[solver]\ndeep_overlap = nan", "solver.deep_overlap"),
        // At the run's hard stop (overlap_limit 0.05 by default) it would never act.
        ("[solver]\ndeep_overlap = 0.05", "solver.deep_overlap"),
        (
            "[solver]\ndeep_overlap = 0.005\ndeep_sweeps = 0",
            "solver.deep_sweeps",
        ),
        // Beyond what chains of deep contacts need, and beyond what one GPU workgroup
        // loops through on a software adapter.
        ("[solver]\ndeep_sweeps = 1001", "solver.deep_sweeps"),
        (
            "[solver]\nmethod = \"apgd\"\ndeep_overlap = 0.005",
            "solver.deep_overlap",
        ),
        ("[compaction]\nsigma_c = \"-1 MPa\"", "compaction.sigma_c"),
        ("[compaction]\nfriction = -0.1", "compaction.friction"),
        ("[test]\nmu = -0.3", "test.mu"),
        ("[test]\nmu = nan", "test.mu"),
        ("[test]\nwall_mu = -1", "test.wall_mu"),
        ("[test]\nsigma3 = 0", "test.sigma3"),
        ("[test]\nsigma3 = nan", "test.sigma3"),
        // A bare number is in Pa: 8 meant as MPa. And beyond the grains' own stiffness.
        ("[test]\nsigma3 = 8", "test.sigma3"),
        ("[test]\nsigma3 = \"999 Pa\"", "test.sigma3"),
        ("[test]\nsigma3 = \"11 GPa\"", "test.sigma3"),
        ("[compaction]\nsigma_c = 8", "compaction.sigma_c"),
        // Too few disks for the default strips (7.5 m each): refused before any work.
        ("[sample]\ndisks = 150", "sample.disks"),
        ("[sample]\ndisks = 1000000000", "sample.disks"),
        ("[test]\nstrip_thickness = 0", "test.strip_thickness"),
        ("[test]\naxial_velocity = 0", "test.axial_velocity"),
        ("[test]\nstrain_end = 0", "test.strain_end"),
        ("[test]\nstrain_end = 1", "test.strain_end"),
        ("[test]\ne_n = 1.5", "test.e_n"),
        ("[test]\ne_t = -2", "test.e_t"),
        ("[equilibrium]\nkinetic_ratio = 0", "equilibrium.kinetic_ratio"),
        (
            "[equilibrium]\nrunaway_kinetic_ratio = -1",
            "equilibrium.runaway_kinetic_ratio",
        ),
        (
            "[equilibrium]\nforce_imbalance = -1",
            "equilibrium.force_imbalance",
        ),
        ("[equilibrium]\nhold_steps = 0", "equilibrium.hold_steps"),
        ("[equilibrium]\nmax_time = 0", "equilibrium.max_time"),
        ("[output]\ndir = \"\"", "output.dir"),
        ("[output]\nseries_every = 0", "output.series_every"),
        ("[output]\nsnapshot_every = -0.01", "output.snapshot_every"),
    ];
    for (text, field) in cases {
        match Config::from_toml_str(text) {
            Err(Error::Invalid {
                field: f, allowed, ..
            }) => {
                assert_eq!(&f, field, "{text}");
                assert!(!allowed.is_empty());
            }
            other => panic!("{text}: expected an invalid `{field}`, got {other:?}"),
        }
    }
}

#[test]
fn overrides_replace_file_values() {
    let mut c = Config::default();
    c.apply(&Overrides {
        disks: Some(5000),
        mu: Some(3.0),
        sigma3: Some("4 MPa".parse().unwrap()),
        strain: Some(0.05),
        seed: Some(7),
        backend: Some(Backend::Cpu),
        out: Some("runs/x".into()),
    });
    c.validate().unwrap();
    assert_eq!(c.sample.disks, 5000);
    assert_eq!(c.test.mu, 3.0);
    assert_eq!(c.test.wall_friction(), 3.0);
    assert_eq!(c.test.sigma3, Pressure(4e6));
    assert_eq!(c.test.strain_end, 0.05);
    assert_eq!(c.sample.seed, 7);
    assert_eq!(c.solver.backend, Backend::Cpu);
    assert_eq!(c.output.dir, PathBuf::from("runs/x"));
    // A backend name is parsed before it becomes an override; a wrong one names its key.
    let e = "tpu".parse::<Backend>().unwrap_err();
    assert!(e.to_string().contains("solver.backend"), "{e}");
    let mut d = Config::default();
    d.apply(&Overrides::default());
    assert_eq!(d, Config::default());
}

#[test]
fn load_names_the_file() {
    let dir = std::env::temp_dir().join(format!("cdlab-config-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bad.toml");
    std::fs::write(&path, "[test]\nmu = \n").unwrap();
    let e = Config::load(&path).unwrap_err().to_string();
    assert!(e.contains("bad.toml") && e.contains("line 2"), "{e}");
    let e = Config::load(dir.join("missing.toml")).unwrap_err().to_string();
    assert!(e.contains("missing.toml"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `solver.deep_overlap` unset means the built-in threshold for the methods that implement
/// the local updates (Gauss-Seidel in both orders and Jacobi) and none for the others,
/// which refuse an explicit value; an explicit value is kept whatever the method.
#[test]
fn an_unset_deep_overlap_follows_the_method() {
    let on = crate::solver::default_deep_overlap_rel();
    for (method, want) in [
        (Method::ColoredGs, on),
        (Method::Gs, on),
        (Method::Jacobi, on),
        (Method::Apgd, 0.0),
        (Method::AndersonGs, 0.0),
    ] {
        let mut c = Config::default();
        c.solver.method = method;
        assert_eq!(c.solver.deep_overlap_rel(), want, "{method:?}");
        c.validate().unwrap();
        c.solver.deep_overlap = Some(0.002);
        assert_eq!(c.solver.deep_overlap_rel(), 0.002, "{method:?}");
    }
}

/// The default configuration is the one source of the protocol's defaults: its hard stop
/// on overlaps is `solver.overlap_limit` (0.05) of `r_min`, as the reference says, in the
/// protocol the benches and `cdlab bench` run too. (They used a second table that stopped
/// at 0.05 m, 0.1 `r_min`.)
#[test]
fn the_default_protocol_follows_the_configuration() {
    let p = Config::with_disks(600).protocol();
    assert_eq!(p.disks, 600);
    assert_eq!(p.step.overlap_limit, 0.05 * p.r_min);
    assert_eq!(p.step.alert, 0.1 * p.r_min);
    assert_eq!(
        p.step.solver.deep_gap,
        crate::solver::default_deep_overlap_rel() * p.r_min
    );
    let mut c = Config::with_disks(600);
    assert_eq!(c.sample.disks, 600);
    c.sample.disks = Config::default().sample.disks;
    assert_eq!(c, Config::default());
}

/// A value of the wrong type in a configuration a program built (the Python package's
/// dicts, as JSON) names its key and value, in words rather than Rust types, and no line of
/// a text nobody wrote; in a file the line stays, in the same words (issue 36, item 17:
/// "line 2: ... invalid value: integer -5, expected usize").
#[test]
fn a_value_of_the_wrong_type_names_its_key_in_plain_words() {
    let json = |text: &str| serde_json::from_str::<serde_json::Value>(text).unwrap();
    match Config::from_json_value(json(r#"{"sample": {"disks": -5}}"#), "<config dict>") {
        Err(Error::Invalid {
            field,
            value,
            allowed,
        }) => {
            assert_eq!((field.as_str(), value.as_str()), ("sample.disks", "-5"));
            assert!(allowed.starts_with("must be a whole number >= 0"), "{allowed}");
            assert!(!allowed.contains("usize"), "{allowed}");
        }
        other => panic!("{other:?}"),
    }
    match Config::from_json_value(json(r#"{"test": {"mu": "much"}}"#), "<config dict>") {
        Err(Error::Invalid {
            field,
            value,
            allowed,
        }) => {
            assert_eq!((field.as_str(), value.as_str()), ("test.mu", "\"much\""));
            assert!(
                allowed.contains("a number") && !allowed.contains("f64"),
                "{allowed}"
            );
        }
        other => panic!("{other:?}"),
    }
    // A key that does not exist is named with its section, like a value.
    match Config::from_json_value(json(r#"{"sample": {"diskz": 300}}"#), "<config dict>") {
        Err(Error::Invalid {
            field,
            value,
            allowed,
        }) => {
            assert_eq!((field.as_str(), value.as_str()), ("sample.diskz", "300"));
            assert!(allowed.contains("unknown field"), "{allowed}");
        }
        other => panic!("{other:?}"),
    }
    // What names no key is a parse error of the source, without a line.
    match Config::from_json_value(json("[1, 2]"), "<config dict>") {
        Err(Error::Parse { path, line: 0, .. }) => assert_eq!(path, Path::new("<config dict>")),
        other => panic!("{other:?}"),
    }
    let text = "[sample]\ndisks = -5\n";
    match Config::from_toml_str(text) {
        Err(e @ Error::Parse { line: 2, .. }) => {
            let m = e.to_string();
            assert!(m.contains("sample.disks") && !m.contains("usize"), "{m}");
        }
        other => panic!("{other:?}"),
    }
}

/// A time step set on the protocol's parameters carries the velocity tolerances made from
/// it along, as the configuration derives them for that step.
#[test]
fn a_new_time_step_derives_its_velocity_tolerances() {
    let mut c = Config::default();
    let mut step = c.protocol().step;
    step.set_dt(2.5e-4);
    c.solver.dt = Duration(2.5e-4);
    let want = c.protocol().step;
    assert_eq!(step.dt, want.dt);
    for (got, want) in [
        (step.solver.velocity_tol, want.solver.velocity_tol),
        (step.solver.open_skip, want.solver.open_skip),
    ] {
        assert!(
            want > 0.0 && ((got - want) / want).abs() < 1e-12,
            "{got} against {want}"
        );
    }
}

/// A configuration given as JSON reads as the same TOML file does: quantities as unit
/// strings or SI numbers, every other key at its default, and validated (a confining
/// stress below zero is refused after it deserialises).
#[test]
fn a_json_configuration_reads_as_the_same_toml_file() {
    let toml = "[sample]\ndisks = 2000\nr_min = \"400 mm\"\n[test]\nsigma3 = \"2 MPa\"\nmu = 0.3\n";
    let json = serde_json::json!({
        "sample": {"disks": 2000, "r_min": "400 mm"},
        "test": {"sigma3": "2 MPa", "mu": 0.3},
    });
    let from_json = Config::from_json_value(json, "<config dict>").unwrap();
    assert_eq!(from_json, Config::from_toml_str(toml).unwrap());
    assert_eq!(from_json.test.sigma3.si(), 2e6);
    assert_eq!(from_json.sample.r_min.si(), 0.4);
    let negative = serde_json::json!({"test": {"sigma3": "-1 MPa"}});
    assert!(Config::from_json_value(negative, "<config dict>").is_err());
}

/// A value the protocol takes as it is has one check, the protocol's: the configuration's
/// error for it is the protocol parameters' own, word for word.
#[test]
fn values_the_protocol_takes_as_they_are_are_checked_by_it() {
    for (setting, field) in [
        ("[sample]\ndisks = 10", "sample.disks"),
        ("[sample]\nr_max = \"0.1 m\"", "sample.r_max"),
        ("[sample]\ndensity = \"1e13 kg/m3\"", "sample.density"),
        ("[solver]\ndt = \"2 s\"", "solver.dt"),
        ("[solver]\ntheta = 0.3", "solver.theta"),
        ("[solver]\ntol = 1.5", "solver.tol"),
        ("[solver]\njacobi_relax = 0.0", "solver.jacobi_relax"),
        ("[test]\nsigma3 = 8", "test.sigma3"),
        ("[test]\nstrain_end = 1.5", "test.strain_end"),
        ("[test]\naxial_velocity = \"1e9 m/s\"", "test.axial_velocity"),
        ("[equilibrium]\nmax_time = \"0 s\"", "equilibrium.max_time"),
    ] {
        let c: Config = toml::from_str(setting).unwrap();
        let from_config = c.validate().unwrap_err();
        let from_protocol = c.protocol().validate().unwrap_err();
        assert_eq!(from_config.to_string(), from_protocol.to_string(), "{setting}");
        assert!(
            matches!(&from_config, crate::Error::Invalid { field: f, .. } if f == field),
            "{setting}: {from_config}"
        );
    }
}
