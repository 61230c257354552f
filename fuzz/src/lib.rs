//! What the fuzz targets share: an FMU's resources written once per
//! process, a logger that keeps the messages, and the checks every target
//! makes through the C ABI (the host's view): no value handed out with
//! fmi2OK is non-finite. A panic anywhere is a crash for libFuzzer, whose
//! panic hook aborts before `catch_unwind` in the FMI layer could turn it
//! into fmi2Error, so internal errors are found too.

use std::cell::RefCell;
use std::ffi::{CStr, CString};
use std::path::PathBuf;
use std::sync::OnceLock;

use fmi_sys::fmi2::*;
use nudyn_contract::plant::{OptionalOutputs, PlantResource};
use nudyn_contract::resource::Resource;
use nudyn_fmu::fmi2::*;

thread_local! {
    /// Messages logged by the FMU in this thread since the last `take_log`.
    static LOG: RefCell<Vec<String>> = const { RefCell::new(Vec::new()) };
}

unsafe extern "C" fn keep_message(
    _environment: fmi2ComponentEnvironment,
    _instance: fmi2String,
    _status: fmi2Status,
    _category: fmi2String,
    message: fmi2String,
) {
    // SAFETY: the FMU passes a NUL-terminated message.
    let text = unsafe { CStr::from_ptr(message) }.to_string_lossy().into_owned();
    LOG.with(|log| log.borrow_mut().push(text));
}

/// The messages logged since the last call.
pub fn take_log() -> Vec<String> {
    LOG.with(|log| std::mem::take(&mut *log.borrow_mut()))
}

/// Callbacks with the keeping logger. fmi-sys types the logger as variadic;
/// the FMU never passes variadic arguments (its format has no conversions).
pub fn callbacks() -> fmi2CallbackFunctions {
    type Plain = unsafe extern "C" fn(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String);
    // SAFETY: on x86-64 SysV a call through the variadic type with no extra
    // arguments is the same as a call of this non-variadic function.
    let logger = unsafe { std::mem::transmute::<Plain, fmi2CallbackLogger>(keep_message) };
    fmi2CallbackFunctions {
        logger,
        allocateMemory: None,
        freeMemory: None,
        stepFinished: None,
        componentEnvironment: std::ptr::null_mut(),
    }
}

/// An example's FMU: its resource URI, GUID and number of Real variables.
pub struct Fmu {
    pub uri: CString,
    /// The resource directory as a path (FMI 3.0 takes a path, not a URI).
    pub path: CString,
    pub guid: CString,
    pub reals: u32,
    pub resource: Vec<u8>,
}

/// `examples/NAME.xml` with every optional output, its resources written
/// under the system's temporary directory once per process.
pub fn example_fmu(name: &str, wrench_bodies: &[&str]) -> Fmu {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../examples").join(format!("{name}.xml"));
    let vehicle = nudyn::mjcf::load_mjcf(&path).expect("example imports").vehicle;
    let wrench_bodies: Vec<String> = wrench_bodies.iter().map(|b| b.to_string()).collect();
    let model = nudyn::model::Model::compile_with_wrench_inputs(&vehicle, &wrench_bodies).expect("example compiles");
    let outputs: OptionalOutputs = "qvel,kinetic_energy,power,momentum".parse().expect("known outputs");
    let resource = PlantResource::new(model, outputs);
    let json = resource.to_json().expect("serializable");
    let dir = scratch_dir(name);
    std::fs::write(dir.join(PlantResource::FILE), &json).expect("resource written");
    Fmu {
        uri: CString::new(format!("file://{}/", dir.display())).expect("no NUL"),
        path: CString::new(format!("{}/", dir.display())).expect("no NUL"),
        guid: CString::new(resource.guid(&json)).expect("no NUL"),
        reals: resource.layout().real_variables().count() as u32,
        resource: json,
    }
}

/// A fresh directory for this process.
pub fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nudyn-fuzz-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch directory");
    dir
}

/// The FMU the call-sequence and state targets drive, made once: the
/// servicer example (a free bus with three wheels and a 4-dof arm, nq = 14
/// and nv = 13 as bus_arm7, 15 actuators and 14 sensors) with wrench
/// inputs on the bus and the hand, so that the `ctrl` and `xfrc_applied`
/// inputs and the `sensordata` outputs are fuzzed with the rest.
pub fn servicer() -> &'static Fmu {
    static SERVICER: OnceLock<Fmu> = OnceLock::new();
    SERVICER.get_or_init(|| example_fmu("servicer", &["bus", "hand"]))
}

/// Instantiates `fmu` for co-simulation; NULL if refused.
pub fn instantiate(uri: &CStr, guid: &CStr) -> fmi2Component {
    instantiate_as(fmi2Type_fmi2CoSimulation, uri, guid)
}

/// Instantiates `fmu` for the interface `kind`; NULL if refused.
pub fn instantiate_as(kind: fmi2Type, uri: &CStr, guid: &CStr) -> fmi2Component {
    let functions = callbacks();
    // SAFETY: valid C strings and callbacks that outlive the call (the FMU copies them).
    unsafe { fmi2Instantiate(c"fuzz".as_ptr(), kind, guid.as_ptr(), uri.as_ptr(), &functions, 0, 0) }
}

/// Reads every Real variable (value references 1..=reals); a read that
/// returns fmi2OK must hand out only finite values.
pub fn check_reals(c: fmi2Component, reals: u32) {
    let vrs: Vec<u32> = (1..=reals).collect();
    let mut values = vec![0.0; vrs.len()];
    // SAFETY: arrays of vrs.len() elements.
    let status = unsafe { fmi2GetReal(c, vrs.as_ptr(), vrs.len(), values.as_mut_ptr()) };
    if status == fmi2Status_fmi2OK {
        if let Some((vr, value)) = vrs.iter().zip(&values).find(|(_, v)| !v.is_finite()) {
            panic!("fmi2GetReal returned fmi2OK with value reference {vr} = {value}");
        }
    }
}

/// The GUID an FMU's resources have, from fmi2Instantiate's refusal of a
/// wrong one ("... whose GUID is '{...}'"), if it got that far.
pub fn actual_guid(uri: &CStr) -> Option<CString> {
    take_log();
    let c = instantiate(uri, c"{not the guid}");
    if !c.is_null() {
        // SAFETY: a live instance.
        unsafe { fmi2FreeInstance(c) };
        panic!("fmi2Instantiate accepted a wrong GUID");
    }
    let log = take_log();
    let message = log.iter().find(|m| m.contains("whose GUID is '"))?;
    let start = message.find("whose GUID is '")? + "whose GUID is '".len();
    let end = start + message[start..].find('\'')?;
    CString::new(&message[start..end]).ok()
}
