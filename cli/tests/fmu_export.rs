//! `nudyn_cli::export::plant::write_fmu`: the archive's entries, a
//! modelDescription that reads back and validates, and a GUID that follows
//! the content.

use std::io::Read;
use std::path::{Path, PathBuf};

use nudyn::model::Model;
use nudyn_cli::export::ExportError;
use nudyn_cli::export::binary::{FMI2_FUNCTIONS, FMI3_FUNCTIONS};
use nudyn_cli::export::plant::{ExportOptions, write_fmu};
use nudyn_cli::export::{FmiVersion, Platform, PlatformBinary};
use nudyn_contract::plant::{OptionalOutputs, PlantResource};
use nudyn_contract::resource::Resource;

fn example(name: &str) -> Model {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../examples").join(name);
    let imported = nudyn::mjcf::load_mjcf(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    Model::compile(&imported.vehicle).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nudyn-fmu-export-{test}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch directory");
    dir
}

/// Every entry of the archive, by name.
fn entries(archive: &Path) -> Vec<(String, Vec<u8>)> {
    let mut zip = zip::ZipArchive::new(std::fs::File::open(archive).expect("archive exists")).expect("a zip file");
    (0..zip.len())
        .map(|i| {
            let mut entry = zip.by_index(i).expect("readable entry");
            let mut bytes = Vec::new();
            entry.read_to_end(&mut bytes).expect("readable entry");
            (entry.name().expect("UTF-8 name").to_string(), bytes)
        })
        .collect()
}

/// `binary` as the FMU's only platform binary.
fn linux64(binary: &Path) -> [PlatformBinary; 1] {
    [PlatformBinary { platform: Platform::Linux64, path: binary.to_path_buf() }]
}

/// A shared library that exports the FMI 2.0 and 3.0 functions (and
/// does nothing), built with gcc: the exporter packs only such a library.
fn stand_in_library(dir: &Path) -> PathBuf {
    stand_in_library_with(dir, &[])
}

/// The stand-in library, built with more gcc flags.
fn stand_in_library_with(dir: &Path, flags: &[&str]) -> PathBuf {
    let source = dir.join("stand_in.c");
    let functions: String = FMI2_FUNCTIONS
        .iter()
        .chain(&FMI3_FUNCTIONS)
        .map(|name| format!("int {name}(void) {{ return 0; }}\n"))
        .collect();
    std::fs::write(&source, functions).unwrap();
    let library = dir.join("libnudyn_fmu.so");
    let status = std::process::Command::new("gcc")
        .args(["-shared", "-fPIC"])
        .args(flags)
        .arg("-o")
        .arg(&library)
        .arg(&source)
        .status()
        .expect("gcc runs");
    assert!(status.success(), "gcc builds the stand-in library");
    library
}

#[test]
fn archive_holds_description_binary_and_resource() {
    let dir = scratch("archive");
    let binary = stand_in_library(&dir);
    let model = example("bus_arm7.xml");
    let outputs: OptionalOutputs = "kinetic_energy,momentum".parse().unwrap();
    let options = ExportOptions { model_identifier: "bus".into(), outputs, fmi_version: FmiVersion::Fmi2 };
    let fmu = dir.join("bus.fmu");
    write_fmu(&model, &options, &linux64(&binary), &fmu).unwrap();

    let entries = entries(&fmu);
    let names: Vec<&str> = entries.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        ["modelDescription.xml", "binaries/linux64/bus.so", "resources/model.json", "documentation/index.html"]
    );
    assert_eq!(entries[1].1, std::fs::read(&binary).unwrap());

    let xml = String::from_utf8(entries[0].1.clone()).unwrap();
    let description = modeldescription::from_xml(&xml).unwrap();
    assert!(modeldescription::validate(&description).is_empty());
    assert_eq!(description.guid, PlantResource::new(model, outputs).guid(&entries[2].1));
    assert_eq!(description.co_simulation.model_identifier, "bus");
    // method, energy_projection, tolerance, max_step, eps (13), theta (14), nu (13), kinetic_energy, momentum (6),
    // der(theta) (14), der(nu) (13)
    assert_eq!(description.model_variables.len(), 4 + 13 + 14 + 13 + 1 + 6 + 14 + 13);
    let me = description.model_exchange.as_ref().expect("model exchange is served");
    assert_eq!((me.model_identifier.as_str(), me.completed_integrator_step_not_needed), ("bus", true));
    let derivatives = &description.model_structure.derivatives;
    assert_eq!(derivatives.len(), 14 + 13);
    for (k, unknown) in derivatives.iter().enumerate() {
        let derivative = &description.model_variables[unknown.index as usize - 1];
        let state = match &derivative.kind {
            modeldescription::VariableKind::Real(real) => real.derivative.expect("a derivative names its state"),
            other => panic!("{other:?}"),
        };
        let state_name = &description.model_variables[state as usize - 1].name;
        assert_eq!(derivative.name, format!("der({state_name})"));
        let expected = if k < 14 { format!("theta[{}]", k + 1) } else { format!("nu[{}]", k - 13) };
        assert_eq!(state_name, &expected);
    }
    let theta8 = description.model_variables.iter().find(|v| v.name == "theta[8]").unwrap();
    assert!(theta8.description.as_deref().unwrap().contains("hinge joint"), "{:?}", theta8.description);
    assert!(theta8.description.as_deref().unwrap().ends_with("(rad)"), "{:?}", theta8.description);
}

#[test]
fn guid_follows_the_content() {
    let resource = PlantResource::new(example("fixed_rig.xml"), OptionalOutputs::default());
    let json = resource.to_json().unwrap();
    let reference = resource.guid(&json);
    assert_eq!(resource.guid(&json), reference, "stable");
    let mut other = resource.clone();
    other.model.links[0].damping += 1.0;
    assert_ne!(other.guid(&other.to_json().unwrap()), reference, "a model change changes the GUID");
    let with_qvel = PlantResource::new(resource.model.clone(), "qvel".parse().unwrap());
    assert_ne!(with_qvel.guid(&json), reference, "a variable change changes the GUID");
    assert_eq!(reference.len(), 38);
}

#[test]
fn bad_model_identifier_is_refused() {
    let dir = scratch("identifier");
    let options = ExportOptions {
        model_identifier: "my model".into(),
        outputs: OptionalOutputs::default(),
        fmi_version: FmiVersion::Fmi2,
    };
    let error = write_fmu(&example("fixed_rig.xml"), &options, &linux64(&dir.join("missing.so")), &dir.join("x.fmu"))
        .unwrap_err();
    assert!(matches!(error, ExportError::ModelIdentifier(_)), "{error}");
}

#[test]
fn a_file_that_is_no_fmu_binary_is_refused_before_anything_is_written() {
    let dir = scratch("not-a-binary");
    let binary = dir.join("libnudyn_fmu.so");
    std::fs::write(&binary, b"not a shared library").unwrap();
    let options = ExportOptions {
        model_identifier: "rig".into(),
        outputs: OptionalOutputs::default(),
        fmi_version: FmiVersion::Fmi2,
    };
    let fmu = dir.join("rig.fmu");
    let error = write_fmu(&example("fixed_rig.xml"), &options, &linux64(&binary), &fmu).unwrap_err();
    assert!(matches!(error, ExportError::Binary { .. }), "{error}");
    assert!(error.to_string().contains("it is not a shared library"), "{error}");
    assert!(!fmu.exists());
}

#[test]
fn fmi3_archive_declares_arrays_of_the_model_sizes() {
    use modeldescription::fmi3::{Variable, from_xml, validate};
    let dir = scratch("fmi3");
    let binary = stand_in_library(&dir);
    let model = example("bus_arm7.xml");
    let outputs: OptionalOutputs = "qvel,momentum".parse().unwrap();
    let options = ExportOptions { model_identifier: "bus".into(), outputs, fmi_version: FmiVersion::Fmi3 };
    let fmu = dir.join("bus3.fmu");
    write_fmu(&model, &options, &linux64(&binary), &fmu).unwrap();

    let entries = entries(&fmu);
    let names: Vec<&str> = entries.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        ["modelDescription.xml", "binaries/x86_64-linux/bus.so", "resources/model.json", "documentation/index.html"]
    );
    let description = from_xml(std::str::from_utf8(&entries[0].1).unwrap()).unwrap();
    assert_eq!(validate(&description), []);
    assert_eq!(description.instantiation_token, PlantResource::new(model.clone(), outputs).guid(&entries[2].1));
    let sizes: Vec<(String, Option<u64>)> = description
        .model_variables
        .variables
        .iter()
        .map(|v| match v {
            Variable::Float64(f) => (f.name.clone(), f.dimensions.first().map(|d| d.start)),
            other => (other.common().name.to_string(), None),
        })
        .collect();
    let (nq, nv) = (Some(model.nq as u64), Some(model.nv as u64));
    let expected = [
        ("time", None),
        ("method", None),
        ("energy_projection", None),
        ("tolerance", None),
        ("max_step", None),
        ("eps", nv),
        ("theta", nq),
        ("nu", nv),
        ("qvel", nv),
        ("momentum", Some(6)),
        ("der(theta)", nq),
        ("der(nu)", nv),
    ];
    assert_eq!(sizes, expected.map(|(n, s)| (n.to_string(), s)));
    // Value references are unique across types, time first.
    let vrs: Vec<u32> = description.model_variables.variables.iter().map(|v| v.common().value_reference).collect();
    assert_eq!(vrs, (0..expected.len() as u32).collect::<Vec<_>>());
}

#[test]
fn debug_sections_stay_out_of_the_fmu() {
    use object::{Object, ObjectSection};
    let dir = scratch("debug-sections");
    let binary = stand_in_library_with(&dir, &["-g"]);
    let section_names = |bytes: &[u8]| -> Vec<String> {
        let file = object::File::parse(bytes).expect("an ELF file");
        file.sections().map(|s| s.name().unwrap_or_default().to_string()).collect()
    };
    let built = std::fs::read(&binary).unwrap();
    assert!(section_names(&built).iter().any(|name| name.starts_with(".debug_")), "gcc -g writes debug sections");
    let options = ExportOptions {
        model_identifier: "rig".into(),
        outputs: OptionalOutputs::default(),
        fmi_version: FmiVersion::Fmi2,
    };
    let fmu = dir.join("rig.fmu");
    write_fmu(&example("fixed_rig.xml"), &options, &linux64(&binary), &fmu).unwrap();
    let packed = entries(&fmu).into_iter().find(|(name, _)| name == "binaries/linux64/rig.so").unwrap().1;
    let names = section_names(&packed);
    assert!(!names.iter().any(|name| name.starts_with(".debug_")), "{names:?}");
    assert!(packed.len() < built.len());
    // What stays is the library: every FMI function still exported, the code to the byte.
    nudyn_cli::export::binary::check_library(Platform::Linux64, &packed, &FMI2_FUNCTIONS, "FMI 2.0").unwrap();
    let text = |bytes: &[u8]| {
        let file = object::File::parse(bytes).unwrap();
        file.section_by_name(".text").unwrap().data().unwrap().to_vec()
    };
    assert_eq!(text(&packed), text(&built));
}
