//! Every system's keys: names, flags, types and the setters of untyped values.

use super::*;
use crate::names::flag_of;
use crate::range::ValueError;
use crate::value::{SetError, Value};

#[test]
fn every_key_name_is_a_parameter_with_a_flag() {
    for kind in SystemKind::ALL {
        let keys = Scenario::keys(kind);
        for (i, k) in keys.iter().enumerate() {
            assert!(
                k.name == "mesh" || flag_of(k.name).is_some(),
                "{kind}: `{}` has no flag in names::PARAMETERS",
                k.name
            );
            assert!(
                keys[..i].iter().all(|o| o.name != k.name),
                "{kind}: `{}` twice",
                k.name
            );
            assert!(
                keys[..i]
                    .iter()
                    .all(|o| (o.table, o.key) != (k.table, k.key)),
                "{kind}: {}.{} twice",
                k.table,
                k.key
            );
        }
    }
}

#[test]
fn every_key_sets_and_records_its_default() {
    // Setting each key to what the record writes of its default changes nothing.
    for kind in SystemKind::ALL {
        let defaults = Scenario::new(kind);
        let text = file::record(&defaults, &keys::Literals::default());
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        std::fs::write(&path, &text).unwrap();
        let back = file::read(&path, &[]).unwrap();
        assert_eq!(back.scenario.kind(), kind);
        assert_eq!(file::record(&back.scenario, &back.literals), text, "{kind}");
    }
}

#[test]
fn untyped_values_are_typed_or_refused_with_the_type() {
    let mut s = Scenario::new(SystemKind::Volumetric);
    s.set("over_relaxation", &Value::Float(1.5)).unwrap();
    s.set("over_relaxation", &Value::Text("adaptive".into()))
        .unwrap();
    assert!(s.set("over_relaxation", &Value::Bool(true)).is_err());
    assert_eq!(
        s.set("steps", &Value::Int(-1)),
        Err(SetError::Value(ValueError::new(
            "steps",
            "-1".into(),
            Some(range::NOT_A_WHOLE_NUMBER.into())
        )))
    );
    s.set("pin", &Value::Text("below:z:0@5".into())).unwrap();
    let Scenario::Volumetric(v) = &s else {
        unreachable!()
    };
    assert_eq!(v.anchors.len(), 1);
    assert!(s.set("nonsense", &Value::Int(1)).is_err());
    let e = s.set("scene", &Value::Text("moon".into())).unwrap_err();
    let SetError::Value(e) = e else {
        panic!("{e:?}")
    };
    assert_eq!(
        names::value_message(&e, names::Spelling::Flag, None),
        "invalid value 'moon' for '--scene <SCENE>'"
    );
    assert!(e.to_string().contains("drop-sphere"), "{e}");
}

#[test]
fn a_serde_scenario_is_the_same_scenario() {
    let mut s = shell::ShellScenario::default();
    s.run.dt = 0.005;
    s.anchors = vec![selection::parse_pin("below:z:0.01@200").unwrap()];
    let json = serde_json::to_value(&s).unwrap();
    assert_eq!(json["run"]["dt"], 0.005);
    assert_eq!(json["anchors"][0]["spec"], "below:z:0.01@200.0");
    let back: shell::ShellScenario = serde_json::from_value(json).unwrap();
    assert_eq!(back, s);
}
