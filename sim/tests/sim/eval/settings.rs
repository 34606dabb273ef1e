//! Settings (`sim::eval::Setting`, the crease and squaring grammars): parsed, and bad ones say why.

use super::*;

#[test]
fn settings_parse_and_bad_ones_say_why() {
    let s = Setting::parse("top-down:0.9").unwrap();
    assert_eq!((s.policy, s.tau), (ViewPolicy::TopDown, 0.9));
    assert_eq!(Setting::parse(&s.name()).unwrap(), s);
    for (bad, why) in [
        ("entropy", "POLICY:TAU"),
        ("entropy:x", "tau"),
        ("entropy:1.5", "outside"),
        ("sideways:0.8", "not a view policy"),
    ] {
        let err = Setting::parse(bad).unwrap_err().to_string();
        assert!(err.contains(why), "{bad}: {err}");
    }
}

#[test]
fn square_turn_settings_within_a_quarter_turn_only() {
    for ok in [0.0, 15.0, 35.0, 90.0] {
        assert_eq!(square_turn_setting(ok).unwrap(), ok);
    }
    for bad in [-1.0, 90.5, f64::NAN, f64::INFINITY] {
        let e = square_turn_setting(bad).unwrap_err().to_string();
        assert!(e.contains("square-turn-deg") && e.contains("0-90"), "{bad}: {e}");
    }
}

#[test]
fn crease_settings_parse_and_bad_ones_say_why() {
    assert_eq!(crease_setting("on").unwrap(), Some(CreaseConfig::default()));
    assert_eq!(crease_setting("off").unwrap(), None);
    let c = crease_setting("3:8:4.5:0.25:120").unwrap().unwrap();
    assert_eq!(
        (c.smooth_radius_px, c.baseline_px, c.min_part_points),
        (3, 8, 120)
    );
    assert!((c.min_valley_m - 0.0045).abs() < 1e-7 && (c.min_valley_ratio - 0.25).abs() < 1e-7);
    assert_eq!(
        c.reattach,
        Some(Reattach::default()),
        "five fields keep step 6's defaults"
    );
    let split_only = crease_setting("split-only").unwrap().unwrap();
    assert_eq!(
        split_only,
        CreaseConfig {
            reattach: None,
            ..CreaseConfig::default()
        }
    );
    let r = crease_setting("2:6:5:0.4:200:15:0.25:0.2:12")
        .unwrap()
        .unwrap()
        .reattach
        .unwrap();
    assert!((r.max_area_m2 - 0.0015).abs() < 1e-7 && (r.max_step_m - 0.012).abs() < 1e-7);
    assert!((r.max_share - 0.25).abs() < 1e-7 && (r.min_outline_share - 0.2).abs() < 1e-7);
    let off = crease_setting("2:6:5:0.4:200:0:0.3:0.15:20").unwrap().unwrap();
    assert_eq!(off.reattach, None, "an area of 0 turns step 6 off");
    for text in [
        "on",
        "off",
        "split-only",
        "3:8:4.5:0.25:120",
        "2:6:5:0.4:200:15:0.25:0.2:12",
    ] {
        let config = crease_setting(text).unwrap();
        let back = crease_setting(&crease_text(config.as_ref())).unwrap();
        assert_eq!(back, config, "{text} -> {}", crease_text(config.as_ref()));
    }
    for (bad, why) in [
        ("maybe", "SMOOTH_PX:BASELINE_PX"),
        ("2:6:5:0.4", "SMOOTH_PX:BASELINE_PX"),
        ("2:6:5:0.4:200:20", "AREA_CM2:SHARE:OUTLINE:STEP_MM"),
        ("2:6:5:0.4:200:20:0.3:0.15:x", "step"),
        ("2:0:5:0.4:200", "at least 1 px"),
        ("2:6:-5:0.4:200", "valley depth"),
        ("2:6:5:nan:200", "ratio"),
        ("2.5:6:5:0.4:200", "smoothing radius"),
    ] {
        let err = crease_setting(bad).unwrap_err().to_string();
        assert!(err.contains(why), "{bad}: {err}");
    }
}
