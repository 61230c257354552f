//! The MJCF importer and the model compiler on arbitrary text: an error,
//! never a panic. A model that compiles is then evaluated at its qpos0 with
//! every quaternion scaled to the edges of floating point (1e-160, 1e300),
//! which must normalize to unit length. Seeds: examples/,
//! tests/fixtures/mjcf/, and the deep trees and extreme orientations that
//! scripts/stress-fmu.sh writes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use nudyn::model::{LinkJoint, Model};

fuzz_target!(|data: &[u8]| {
    let Ok(xml) = std::str::from_utf8(data) else { return };
    let Ok(imported) = nudyn::mjcf::parse_mjcf(xml) else { return };
    let Ok(model) = Model::compile(&imported.vehicle) else { return };
    let mut ws = model.workspace();
    let quaternions: Vec<usize> =
        model.links.iter().filter(|l| l.joint == LinkJoint::Ball).map(|l| l.qpos_adr).collect();
    for scale in [1e-160, 1e300] {
        let mut theta = model.qpos0.clone();
        quaternions.iter().for_each(|&k| theta[k..k + 4].iter_mut().for_each(|c| *c *= scale));
        if ws.set_configuration(&model, &theta).is_ok() {
            for &k in &quaternions {
                let norm = ws.theta.as_slice()[k..k + 4].iter().map(|c| c * c).sum::<f64>().sqrt();
                assert!((norm - 1.0).abs() < 1e-15, "quaternion at theta[{k}] scaled by {scale:e}: norm {norm}");
            }
        }
    }
});
