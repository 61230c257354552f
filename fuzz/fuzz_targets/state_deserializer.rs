//! fmi2DeSerializeFMUstate on arbitrary bytes, and on a valid blob of the
//! bus FMU with bytes flipped and, half the time, the checksum made to
//! match (as a forged blob would), so that the checks behind the checksum
//! are reached. Whatever is accepted and restored must step and read out
//! as refused or finite.
#![no_main]

use std::sync::OnceLock;

use fmi_sys::fmi2::*;
use libfuzzer_sys::fuzz_target;
use nudyn_fmu::fmi2::*;
use nudyn_fuzz::{check_reals, instantiate, servicer};

/// FNV-1a, the blob's checksum (fmu/src/snapshot.rs).
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |hash, &b| (hash ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3))
}

/// A valid serialized state of the servicer FMU (with actuators) after two steps.
fn valid_blob() -> &'static [u8] {
    static BLOB: OnceLock<Vec<u8>> = OnceLock::new();
    BLOB.get_or_init(|| unsafe {
        let c = instantiate(&servicer().uri, &servicer().guid);
        fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0);
        fmi2EnterInitializationMode(c);
        fmi2ExitInitializationMode(c);
        fmi2DoStep(c, 0.0, 0.01, 1);
        fmi2DoStep(c, 0.01, 0.01, 1);
        let mut state: fmi2FMUstate = std::ptr::null_mut();
        fmi2GetFMUstate(c, &mut state);
        let mut size = 0;
        fmi2SerializedFMUstateSize(c, state, &mut size);
        let mut blob = vec![0u8; size];
        fmi2SerializeFMUstate(c, state, blob.as_mut_ptr() as *mut fmi2Byte, size);
        fmi2FreeInstance(c);
        blob
    })
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else { return };
    let blob = if mode < 128 {
        rest.to_vec()
    } else {
        // rest: pairs (offset, xor) applied to the valid blob.
        let mut blob = valid_blob().to_vec();
        for pair in rest.chunks_exact(3) {
            let at = usize::from(u16::from_le_bytes([pair[0], pair[1]])) % blob.len();
            blob[at] ^= pair[2];
        }
        if mode & 1 == 1 {
            let contents = blob.len() - 8;
            let checksum = fnv1a(&blob[..contents]);
            blob[contents..].copy_from_slice(&checksum.to_le_bytes());
        }
        blob
    };
    let fmu = servicer();
    let c = instantiate(&fmu.uri, &fmu.guid);
    // SAFETY: a live instance, freed once at the end.
    unsafe {
        fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0);
        fmi2EnterInitializationMode(c);
        fmi2ExitInitializationMode(c);
        let mut state: fmi2FMUstate = std::ptr::null_mut();
        if fmi2DeSerializeFMUstate(c, blob.as_ptr() as *const fmi2Byte, blob.len(), &mut state) == fmi2Status_fmi2OK
            && fmi2SetFMUstate(c, state) == fmi2Status_fmi2OK
        {
            check_reals(c, fmu.reals);
            let mut time = 0.0;
            fmi2GetRealStatus(c, fmi2StatusKind_fmi2LastSuccessfulTime, &mut time);
            fmi2DoStep(c, time, 0.01, 1);
        }
        check_reals(c, fmu.reals);
        fmi2FreeInstance(c);
    }
});
