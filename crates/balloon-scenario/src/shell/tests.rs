//! The shell scenario's checks across keys and its builder.

use super::*;
use crate::gas::GasControl;
use crate::range::End::{Closed, Open};
use crate::range::Real;

#[test]
fn defaults_are_the_library_s_and_check() {
    let s = ShellScenario::default();
    s.validate().unwrap();
    let p = s.integrator_params();
    let d = balloon::shell::default_integrator_params();
    assert_eq!(format!("{p:?}"), format!("{d:?}"));
    assert_eq!(s.run.dt, balloon::shell::DEFAULT_DT);
    assert!(Real::new(Open(0.0), Closed(1.0)).contains(s.run.dt));
}

#[test]
fn keys_that_do_not_go_together_are_named() {
    let mut s = ShellScenario::default();
    s.gas.model = GasControl::Volume;
    assert_eq!(
        s.validate().unwrap_err().to_string(),
        "`gas` = volume is a static control: add `static`"
    );
    s.run.static_solve = true;
    assert!(
        s.validate()
            .unwrap_err()
            .to_string()
            .contains("`volume_ratio`")
    );
    s.gas.volume_ratio = Some(1.5);
    assert_eq!(s.static_points(), Ok(vec![Some(1.5)]));
    s.gas.model = GasControl::Pump;
    s.gas.volume_ratio = None;
    let e = s.validate().unwrap_err().to_string();
    assert!(
        e.contains("rest amount") && e.contains("`gas` = constant `pressure`"),
        "{e}"
    );
    let mut s = ShellScenario::default();
    s.run.steps = 0;
    s.output.frame_every = 0;
    assert!(
        s.validate()
            .unwrap_err()
            .to_string()
            .contains("`steps` is 0")
    );
    let mut s = ShellScenario::default();
    s.mesh.transform = Some(vec![1.0; 4]);
    assert!(s.validate().unwrap_err().to_string().contains("12 numbers"));
}
