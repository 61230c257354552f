//! fmi2Instantiate on an arbitrary resources/model.json. Once with a wrong
//! GUID (the loader reads, parses and checks the file, then refuses the
//! GUID and names the right one); then, if the file got that far, with the
//! right GUID, which a forged resource would have: initialization, a few
//! steps and every output must then be refused or finite. Seeds: the
//! examples' model.json.
#![no_main]

use std::ffi::CString;
use std::sync::OnceLock;

use fmi_sys::fmi2::*;
use libfuzzer_sys::fuzz_target;
use nudyn_fmu::fmi2::*;
use nudyn_fuzz::{actual_guid, check_reals, instantiate, scratch_dir};

fuzz_target!(|data: &[u8]| {
    static DIR: OnceLock<(std::path::PathBuf, CString)> = OnceLock::new();
    let (dir, uri) = DIR.get_or_init(|| {
        let dir = scratch_dir("resource");
        let uri = CString::new(format!("file://{}/", dir.display())).expect("no NUL");
        (dir, uri)
    });
    std::fs::write(dir.join("model.json"), data).expect("resource written");
    let Some(guid) = actual_guid(uri) else { return };
    let c = instantiate(uri, &guid);
    assert!(!c.is_null(), "fmi2Instantiate refused the GUID it named");
    // SAFETY: a live instance, freed once at the end.
    unsafe {
        fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0);
        fmi2EnterInitializationMode(c);
        if fmi2ExitInitializationMode(c) == fmi2Status_fmi2OK {
            for k in 0..3 {
                fmi2DoStep(c, f64::from(k) * 0.01, 0.01, 1);
            }
        }
        // Enough value references for any layout the resource can declare in this input.
        check_reals(c, 2 + 3 * data.len().min(4096) as u32);
        fmi2FreeInstance(c);
    }
});
