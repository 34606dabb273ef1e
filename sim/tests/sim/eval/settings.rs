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
    let split_only = crease_setting("split-only").unwrap().unwrap();
    assert_eq!(
        split_only,
        CreaseConfig {
            reattach: None,
            ..CreaseConfig::default()
        }
    );
    for text in ["on", "off", "split-only"] {
        let config = crease_setting(text).unwrap();
        assert_eq!(crease_text(config.as_ref()), text);
    }
    let other = CreaseConfig {
        baseline_px: 9,
        ..CreaseConfig::default()
    };
    assert!(crease_text(Some(&other)).contains("baseline_px: 9"));
    for bad in ["maybe", "2:6:5:0.4:200", "ON", ""] {
        let err = crease_setting(bad).unwrap_err().to_string();
        assert!(err.contains("on, off or split-only"), "{bad}: {err}");
    }
}
