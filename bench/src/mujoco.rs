//! MuJoCo's C API, loaded at run time from the `libmujoco.so` that the
//! mujoco Python package ships (its path is given on the command line), so
//! that `mj_forward` runs natively in the same process and the same timing
//! loop as nudyn. Only functions are used, never struct fields: the model
//! is the binary file (mj_saveModel) the driver writes from its MjModel,
//! with contacts and constraints off, and the state goes in through
//! `mj_setState`.

use std::ffi::{CString, c_char, c_int, c_void};
use std::path::Path;

use anyhow::{Context, Result, bail};
use libloading::Library;

/// `mjSTATE_QPOS` and `mjSTATE_QVEL` of `mjtState` (mjtype.h).
const STATE_QPOS: c_int = 1 << 1;
const STATE_QVEL: c_int = 1 << 2;

type StageFn = unsafe extern "C" fn(*const c_void, *mut c_void);

/// Which of MuJoCo's computations one evaluation runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pipeline {
    /// `mj_forward`: everything, with sensors, actuation and the constraint
    /// stage (which finds no constraint with contacts off).
    Forward,
    /// `mj_fwdPosition` + `mj_fwdVelocity` + `mj_fwdAcceleration`: the
    /// position stage (kinematics, CRB, factorization, and the collision and
    /// constraint steps, here empty), velocity stage (passive forces and
    /// the bias forces by RNE) and the smooth acceleration, without sensors,
    /// actuation, energy and the constraint stage.
    Stages,
    /// `mj_kinematics` + `mj_comPos` + `mj_makeM` + `mj_factorM` +
    /// `mj_fwdVelocity` + `mj_fwdAcceleration`: only what the smooth
    /// dynamics needs — the closest match to nudyn's ν̇.
    Smooth,
}

impl Pipeline {
    /// All pipelines, most complete first.
    pub const ALL: [Pipeline; 3] = [Pipeline::Forward, Pipeline::Stages, Pipeline::Smooth];

    /// The name in the results.
    pub fn name(self) -> &'static str {
        match self {
            Pipeline::Forward => "mj_forward",
            Pipeline::Stages => "mj_fwdPosition+Velocity+Acceleration",
            Pipeline::Smooth => "mj_kinematics+comPos+makeM+factorM+fwdVelocity+fwdAcceleration",
        }
    }
}

/// The loaded library and the functions the benchmark calls.
pub struct Api {
    load_model: unsafe extern "C" fn(*const c_char, *const c_void) -> *mut c_void,
    make_data: unsafe extern "C" fn(*const c_void) -> *mut c_void,
    delete_data: unsafe extern "C" fn(*mut c_void),
    delete_model: unsafe extern "C" fn(*mut c_void),
    state_size: unsafe extern "C" fn(*const c_void, c_int) -> c_int,
    set_state: unsafe extern "C" fn(*const c_void, *mut c_void, *const f64, c_int),
    forward: StageFn,
    fwd_position: StageFn,
    fwd_velocity: StageFn,
    fwd_acceleration: StageFn,
    kinematics: StageFn,
    com_pos: StageFn,
    make_m: StageFn,
    factor_m: StageFn,
    // Declared last: dropped after the function pointers above stop being used.
    _library: Library,
}

impl Api {
    /// Loads `libmujoco.so` from `path`.
    pub fn load(path: &Path) -> Result<Api> {
        // SAFETY: loading MuJoCo runs its static initializers only; every
        // symbol below is declared with its C signature from mujoco.h (4.0).
        unsafe {
            let library = Library::new(path).with_context(|| format!("cannot load {}", path.display()))?;
            macro_rules! symbol {
                ($name:literal) => {
                    *library.get($name).with_context(|| {
                        format!("{} has no {}", path.display(), String::from_utf8_lossy(&$name[..$name.len() - 1]))
                    })?
                };
            }
            Ok(Api {
                load_model: symbol!(b"mj_loadModel\0"),
                make_data: symbol!(b"mj_makeData\0"),
                delete_data: symbol!(b"mj_deleteData\0"),
                delete_model: symbol!(b"mj_deleteModel\0"),
                state_size: symbol!(b"mj_stateSize\0"),
                set_state: symbol!(b"mj_setState\0"),
                forward: symbol!(b"mj_forward\0"),
                fwd_position: symbol!(b"mj_fwdPosition\0"),
                fwd_velocity: symbol!(b"mj_fwdVelocity\0"),
                fwd_acceleration: symbol!(b"mj_fwdAcceleration\0"),
                kinematics: symbol!(b"mj_kinematics\0"),
                com_pos: symbol!(b"mj_comPos\0"),
                make_m: symbol!(b"mj_makeM\0"),
                factor_m: symbol!(b"mj_factorM\0"),
                _library: library,
            })
        }
    }
}

/// One MuJoCo model and its data.
pub struct Simulation<'a> {
    api: &'a Api,
    model: *mut c_void,
    data: *mut c_void,
    /// MuJoCo's nq and nv.
    pub nq: usize,
    pub nv: usize,
}

impl<'a> Simulation<'a> {
    /// Loads the binary model (mj_saveModel's file) at `path`.
    pub fn load(api: &'a Api, path: &Path) -> Result<Simulation<'a>> {
        let c_path = CString::new(path.to_string_lossy().as_bytes()).context("path contains a NUL byte")?;
        // SAFETY: a NUL-terminated path and no VFS.
        let model = unsafe { (api.load_model)(c_path.as_ptr(), std::ptr::null()) };
        if model.is_null() {
            bail!("MuJoCo cannot load the binary model {}", path.display());
        }
        // SAFETY: `model` is a valid mjModel from mj_loadXML.
        let (data, nq, nv) = unsafe {
            ((api.make_data)(model), (api.state_size)(model, STATE_QPOS), (api.state_size)(model, STATE_QVEL))
        };
        if data.is_null() {
            // SAFETY: not used after this.
            unsafe { (api.delete_model)(model) };
            bail!("MuJoCo cannot allocate data for {}", path.display());
        }
        Ok(Simulation { api, model, data, nq: nq as usize, nv: nv as usize })
    }

    /// Sets qpos and qvel (time and everything else as after mj_makeData).
    pub fn set_state(&mut self, qpos: &[f64], qvel: &[f64]) -> Result<()> {
        if qpos.len() != self.nq || qvel.len() != self.nv {
            bail!(
                "MuJoCo's model has nq = {}, nv = {}; the state has {} and {}",
                self.nq,
                self.nv,
                qpos.len(),
                qvel.len()
            );
        }
        let state: Vec<f64> = qpos.iter().chain(qvel).copied().collect();
        // SAFETY: `state` has nq + nv entries, the size of the QPOS|QVEL state.
        unsafe { (self.api.set_state)(self.model, self.data, state.as_ptr(), STATE_QPOS | STATE_QVEL) };
        Ok(())
    }

    /// One evaluation of `pipeline` at the current state.
    pub fn evaluate(&mut self, pipeline: Pipeline) {
        let api = self.api;
        let stages: &[StageFn] = match pipeline {
            Pipeline::Forward => &[api.forward],
            Pipeline::Stages => &[api.fwd_position, api.fwd_velocity, api.fwd_acceleration],
            Pipeline::Smooth => {
                &[api.kinematics, api.com_pos, api.make_m, api.factor_m, api.fwd_velocity, api.fwd_acceleration]
            }
        };
        for stage in stages {
            // SAFETY: a valid model and its data.
            unsafe { stage(self.model, self.data) };
        }
    }
}

impl Drop for Simulation<'_> {
    fn drop(&mut self) {
        // SAFETY: made by mj_makeData / mj_loadXML, freed once.
        unsafe {
            (self.api.delete_data)(self.data);
            (self.api.delete_model)(self.model);
        }
    }
}
