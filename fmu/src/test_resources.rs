//! Unit tests' FMU resources: an example's `model.json` in a fresh directory.

use std::ffi::CString;
use std::path::PathBuf;

use nudyn_contract::plant::{Layout, OptionalOutputs, PlantResource};
use nudyn_contract::resource::Resource;

/// `examples/<example>.xml`'s plant resource written to a directory of its
/// own for test `test`: (the directory, the GUID, its FMI 2.0 variables).
pub fn write(example: &str, test: &str) -> (PathBuf, CString, Layout) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("../examples/{example}.xml"));
    let vehicle = nudyn::mjcf::load_mjcf(&path).expect("example imports").vehicle;
    let model = nudyn::model::Model::compile(&vehicle).expect("example compiles");
    let resource = PlantResource::new(model, OptionalOutputs::default());
    let json = resource.to_json().expect("serializable");
    let dir = std::env::temp_dir().join(format!("nudyn-fmu-{test}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    std::fs::write(dir.join("model.json"), &json).expect("resource written");
    (dir, CString::new(resource.guid(&json)).expect("no NUL"), resource.layout())
}
