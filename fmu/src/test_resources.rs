//! Unit tests' FMU resources (an example's `model.json` or
//! `controller.json` in a fresh directory) and instances of them.

use std::ffi::{CStr, CString};
use std::path::{Path, PathBuf};

use fmi_sys::fmi2::{fmi2CallbackFunctions, fmi2Component, fmi2Type};

use nudyn::control::ControlLaw;
use nudyn_contract::controller::{ControllerLayout, ControllerResource};
use nudyn_contract::plant::{Layout, OptionalOutputs, PlantResource};
use nudyn_contract::resource::Resource;

/// `examples/<example>.xml` compiled.
fn example(example: &str) -> (nudyn::vehicle::Vehicle, nudyn::model::Model) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("../examples/{example}.xml"));
    let vehicle = nudyn::mjcf::load_mjcf(&path).expect("example imports").vehicle;
    let model = nudyn::model::Model::compile(&vehicle).expect("example compiles");
    (vehicle, model)
}

/// `examples/<example>.xml` compiled, as its plant resource holds it.
pub fn model(example: &str) -> nudyn::model::Model {
    self::example(example).1
}

/// `resource` written to a directory of its own for test `test`: (the
/// directory, the GUID).
fn write_resource<R: Resource>(resource: &R, test: &str) -> (PathBuf, CString) {
    let json = resource.to_json().expect("serializable");
    let dir = std::env::temp_dir().join(format!("nudyn-fmu-{test}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    std::fs::write(dir.join(R::FILE), &json).expect("resource written");
    (dir, CString::new(resource.guid(&json)).expect("no NUL"))
}

/// `examples/<example>.xml`'s plant resource written for test `test`:
/// (the directory, the GUID, its FMI 2.0 variables).
pub fn write(example: &str, test: &str) -> (PathBuf, CString, Layout) {
    let resource = PlantResource::new(self::example(example).1, OptionalOutputs::default());
    let (dir, guid) = write_resource(&resource, test);
    (dir, guid, resource.layout())
}

/// The controller resource of `examples/<example>.xml` with the law of
/// `law` (its joints', or a pose law of the body it names) written for
/// test `test`: (the directory, the GUID, its variables).
pub fn write_controller(example: &str, law: Option<&str>, test: &str) -> (PathBuf, CString, ControllerLayout) {
    let (vehicle, model) = self::example(example);
    let law = match law {
        Some(body) => ControlLaw::pose(&vehicle, &model, body),
        None => ControlLaw::joints(&model),
    };
    let resource = ControllerResource::new(model, law.expect("a law of the example"));
    let (dir, guid) = write_resource(&resource, test);
    (dir, guid, resource.layout())
}

/// The `file://` URI of resource directory `dir`, as FMI 2.0 passes it.
pub fn uri(dir: &Path) -> CString {
    CString::new(format!("file://{}/", dir.display())).expect("no NUL")
}

/// An FMI 2.0 instance of `kind` of the resources at `uri`, without a
/// logger (null when instantiation is refused).
pub fn instantiate_fmi2(kind: fmi2Type, uri: &CStr, guid: &CStr) -> fmi2Component {
    let functions = fmi2CallbackFunctions {
        logger: None,
        allocateMemory: None,
        freeMemory: None,
        stepFinished: None,
        componentEnvironment: std::ptr::null_mut(),
    };
    // SAFETY: every pointer is valid for the call; the FMU copies the strings.
    unsafe { crate::fmi2::fmi2Instantiate(c"test".as_ptr(), kind, guid.as_ptr(), uri.as_ptr(), &functions, 0, 0) }
}
