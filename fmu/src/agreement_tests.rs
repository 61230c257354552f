//! A property test over random vehicles and option sets: for every plant
//! variable, the FMI 2.0 value reference the layout gives, the FMI 3.0
//! variable and element the contract's FMI 3.0 table gives (arrays or
//! `--fmi3-scalars`), and the FMU's own get and set through the FMI 2.0 and
//! FMI 3.0 functions agree. Each settable element is set to a value of its
//! own through one version and read back through both; every other element
//! reads the same, to the bit, through both.

use std::ffi::CString;

use fmi_sys::fmi2::*;
use fmi_sys::fmi3::*;
use proptest::prelude::*;

use nudyn::model::Model;
use nudyn_contract::fmi3::ValueType;
use nudyn_contract::plant::{OptionalOutputs, PlantResource};
use nudyn_contract::resource::Resource;

use crate::fmi2::*;
use crate::fmi3::*;

/// One joint of a random vehicle: its MJCF type and whether it is limited.
#[derive(Clone, Debug)]
struct JointSpec {
    kind: &'static str,
    limited: bool,
    actuated: bool,
    sensed: bool,
}

/// One body: its parent (None: the world) and joints.
#[derive(Clone, Debug)]
struct BodySpec {
    parent: Option<usize>,
    joints: Vec<JointSpec>,
    /// A `framepos` sensor on it.
    sensed: bool,
    /// Its wrench is an input (`--wrench-inputs`).
    wrench: bool,
}

fn joint(kind: &'static str) -> impl Strategy<Value = JointSpec> {
    (any::<bool>(), any::<bool>(), any::<bool>()).prop_map(move |(limited, actuated, sensed)| JointSpec {
        kind,
        limited: limited && kind != "free",
        // Motors and joint sensors on hinges and slides.
        actuated: actuated && matches!(kind, "hinge" | "slide"),
        sensed: sensed && matches!(kind, "hinge" | "slide"),
    })
}

/// A body's joints: none (welded), a free joint (at the world only), up
/// to three hinges and slides, or slides and a ball last, as MuJoCo requires.
fn joints(at_world: bool) -> impl Strategy<Value = Vec<JointSpec>> {
    let hinge_or_slide = prop_oneof![joint("hinge"), joint("slide")];
    // Hinges and a ball at one point would turn it about more than three axes.
    let ball = (proptest::collection::vec(joint("slide"), 0..2), joint("ball")).prop_map(|(mut joints, ball)| {
        joints.push(ball);
        joints
    });
    let chain = prop_oneof![proptest::collection::vec(hinge_or_slide, 0..4), ball];
    if at_world { prop_oneof![chain, joint("free").prop_map(|j| vec![j])].boxed() } else { chain.boxed() }
}

fn vehicles() -> impl Strategy<Value = Vec<BodySpec>> {
    (1..6usize)
        .prop_flat_map(|n| {
            let bodies: Vec<_> = (0..n)
                .map(|i| {
                    // Parent i stands for the world.
                    (0..=i).prop_flat_map(move |parent| {
                        let parent = (parent < i).then_some(parent);
                        (joints(parent.is_none()), any::<bool>(), any::<bool>())
                            .prop_map(move |(joints, sensed, wrench)| BodySpec { parent, joints, sensed, wrench })
                    })
                })
                .collect();
            bodies
        })
        .prop_filter("a vehicle moves", |bodies| bodies.iter().any(|b| !b.joints.is_empty()))
}

/// The MJCF file of `bodies`, nested as their parents say.
fn mjcf(bodies: &[BodySpec]) -> String {
    fn body(bodies: &[BodySpec], b: usize, xml: &mut String, actuators: &mut String, sensors: &mut String) {
        const AXES: [&str; 3] = ["1 0 0", "0 1 0", "0 0 1"];
        xml.push_str(&format!(
            "<body name=\"b{b}\" pos=\"0.1 0.2 {}\"><inertial pos=\"0.01 0 0\" mass=\"{}\" diaginertia=\"0.1 0.12 0.14\"/>",
            0.3 + b as f64 * 0.1,
            1.0 + b as f64
        ));
        for (k, joint) in bodies[b].joints.iter().enumerate() {
            let name = format!("j{b}_{k}");
            let range = match (joint.limited, joint.kind) {
                (true, "ball") => " range=\"0 1\"".to_string(),
                (true, _) => " range=\"-0.5 0.5\"".to_string(),
                _ => String::new(),
            };
            xml.push_str(&format!("<joint name=\"{name}\" type=\"{}\" axis=\"{}\"{range}/>", joint.kind, AXES[k % 3]));
            if joint.actuated {
                actuators.push_str(&format!("<motor joint=\"{name}\" gear=\"2\"/>"));
            }
            if joint.sensed {
                sensors.push_str(&format!("<jointpos joint=\"{name}\"/><jointvel joint=\"{name}\"/>"));
            }
        }
        if bodies[b].sensed {
            sensors.push_str(&format!("<framepos objtype=\"body\" objname=\"b{b}\"/>"));
        }
        for child in (0..bodies.len()).filter(|&c| bodies[c].parent == Some(b)) {
            body(bodies, child, xml, actuators, sensors);
        }
        xml.push_str("</body>");
    }
    let (mut xml, mut actuators, mut sensors) = (String::new(), String::new(), String::new());
    for root in (0..bodies.len()).filter(|&b| bodies[b].parent.is_none()) {
        body(bodies, root, &mut xml, &mut actuators, &mut sensors);
    }
    format!(
        "<mujoco model=\"random\"><worldbody>{xml}</worldbody><actuator>{actuators}</actuator>\
         <sensor>{sensors}</sensor></mujoco>"
    )
}

fn outputs() -> impl Strategy<Value = OptionalOutputs> {
    proptest::collection::vec(any::<bool>(), OptionalOutputs::NAMES.len()).prop_map(|chosen| {
        let names: Vec<&str> =
            OptionalOutputs::NAMES.iter().zip(chosen).filter(|(_, chosen)| *chosen).map(|(name, _)| *name).collect();
        names.join(",").parse().expect("known names")
    })
}

/// The FMU's resource directory for `resource` (one per case and process).
fn resource_directory(resource: &PlantResource, case: usize) -> (std::path::PathBuf, CString) {
    let json = resource.to_json().expect("serializable");
    let dir = std::env::temp_dir().join(format!("nudyn-fmu-agreement-{}-{case}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    std::fs::write(dir.join(PlantResource::FILE), &json).expect("resource written");
    (dir, CString::new(resource.guid(&json)).expect("no NUL"))
}

/// A value of its own for the settable element with FMI 2.0 value reference `vr`.
fn own_value(vr: u32) -> f64 {
    0.5 + 1e-3 * f64::from(vr)
}

static CASE: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    #[test]
    fn fmi2_and_fmi3_value_references_and_the_fmus_get_and_set_agree(
        bodies in vehicles(),
        outputs in outputs(),
        scalars in any::<bool>(),
    ) {
        let xml = mjcf(&bodies);
        let vehicle = nudyn::mjcf::parse_mjcf(&xml).map_err(|e| TestCaseError::fail(format!("{e}\n{xml}")))?.vehicle;
        // A wrench input on a body that moves (a joint on it or on an ancestor).
        let moves = |mut b: usize| loop {
            if !bodies[b].joints.is_empty() {
                break true;
            }
            match bodies[b].parent {
                Some(parent) => b = parent,
                None => break false,
            }
        };
        let wrenches: Vec<String> =
            (0..bodies.len()).filter(|&b| bodies[b].wrench && moves(b)).map(|b| format!("b{b}")).collect();
        let model = Model::compile_with_wrench_inputs(&vehicle, &wrenches)
            .map_err(|e| TestCaseError::fail(format!("{e}\n{xml}")))?;
        let resource = PlantResource { fmi3_scalars: scalars, ..PlantResource::new(model, outputs) };
        let layout = resource.layout();
        let table = resource.fmi3_variables();
        let (dir, guid) = resource_directory(&resource, CASE.fetch_add(1, std::sync::atomic::Ordering::Relaxed));
        let uri = crate::test_resources::uri(&dir);
        let path = CString::new(format!("{}/", dir.display())).expect("no NUL");

        unsafe {
            let fmi2 = crate::test_resources::instantiate_fmi2(fmi2Type_fmi2CoSimulation, &uri, &guid);
            prop_assert!(!fmi2.is_null(), "{xml}");
            let fmi3 = fmi3InstantiateCoSimulation(c"agreement".as_ptr(), guid.as_ptr(), path.as_ptr(), false, false,
                false, false, std::ptr::null(), 0, std::ptr::null_mut(), None, None);
            prop_assert!(!fmi3.is_null(), "{xml}");
            prop_assert_eq!(fmi2SetupExperiment(fmi2, 0, 0.0, 0.0, 0, 0.0), fmi2Status_fmi2OK);
            prop_assert_eq!(fmi2EnterInitializationMode(fmi2), fmi2Status_fmi2OK);
            prop_assert_eq!(fmi3EnterInitializationMode(fmi3, false, 0.0, 0.0, false, 0.0), fmi3Status_fmi3OK);

            // Every element: its FMI 2.0 name from the table's entry is the
            // FMI 3.0 element's, and the FMU names and kinds it the same.
            let elements: Vec<_> = layout.elements().collect();
            prop_assert_eq!(elements.len(), table.iter().filter(|v| v.value_type == ValueType::Float64).map(|v| v.len).sum::<usize>());
            for element in &elements {
                let (holder, k) = table.real_element(element.value_reference).expect("every Real has an FMI 3.0 variable");
                let fmi3_name = if holder.array {
                    match holder.name.strip_prefix("der(") {
                        Some(state) => format!("der({}[{}])", state.trim_end_matches(')'), k + 1),
                        None => format!("{}[{}]", holder.name, k + 1),
                    }
                } else {
                    holder.name.clone()
                };
                prop_assert_eq!(&fmi3_name, &element.name());
                prop_assert_eq!(layout.real_variable(element.value_reference), Some(element.variable()));
                prop_assert_eq!(layout.value_reference(element.variable()), Some(element.value_reference));
            }

            // Settable elements: set through FMI 2.0 on one instance, through FMI 3.0's whole variables on the other.
            let settable: Vec<u32> = elements.iter().filter(|e| e.kind().refuses_set(false).is_none()).map(|e| e.value_reference).collect();
            let values: Vec<f64> = settable.iter().map(|&vr| own_value(vr)).collect();
            prop_assert_eq!(fmi2SetReal(fmi2, settable.as_ptr(), settable.len(), values.as_ptr()), fmi2Status_fmi2OK);
            for variable in table.iter().filter(|v| v.value_type == ValueType::Float64) {
                if variable.elements().all(|vr| settable.contains(&vr)) {
                    let values: Vec<f64> = variable.elements().map(own_value).collect();
                    let vr = [variable.value_reference];
                    prop_assert_eq!(fmi3SetFloat64(fmi3, vr.as_ptr(), 1, values.as_ptr(), values.len()), fmi3Status_fmi3OK);
                }
            }
            let read_fmi3 = |vr: u32| -> Result<f64, TestCaseError> {
                let (holder, k) = table.real_element(vr).expect("held");
                let mut values = vec![f64::NAN; holder.len];
                let status = fmi3GetFloat64(fmi3, [holder.value_reference].as_ptr(), 1, values.as_mut_ptr(), values.len());
                prop_assert_eq!(status, fmi3Status_fmi3OK, "{}", holder.name);
                Ok(values[k])
            };
            for &vr in &settable {
                let mut value = f64::NAN;
                prop_assert_eq!(fmi2GetReal(fmi2, [vr].as_ptr(), 1, &mut value), fmi2Status_fmi2OK);
                prop_assert_eq!(value, own_value(vr), "FMI 2.0 vr {}", vr);
                prop_assert_eq!(read_fmi3(vr)?, own_value(vr), "FMI 2.0 vr {} through FMI 3.0", vr);
            }

            // After initialization (quaternions normalized), every element reads the same through both.
            prop_assert_eq!(fmi2ExitInitializationMode(fmi2), fmi2Status_fmi2OK);
            prop_assert_eq!(fmi3ExitInitializationMode(fmi3), fmi3Status_fmi3OK);
            for element in &elements {
                let vr = element.value_reference;
                let mut value = f64::NAN;
                prop_assert_eq!(fmi2GetReal(fmi2, [vr].as_ptr(), 1, &mut value), fmi2Status_fmi2OK, "{}", element.name());
                prop_assert_eq!(value.to_bits(), read_fmi3(vr)?.to_bits(), "{}: {}", element.name(), value);
            }
            fmi2FreeInstance(fmi2);
            fmi3FreeInstance(fmi3);
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
