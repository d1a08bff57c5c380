//! One instance of a model, driven through the FMI functions.

use super::*;

// One instance, driven through the FMI functions
// ---------------------------------------------------------------------------

/// An instance of model `M` with its log book and one saved FMU state.
pub struct Fmu<M: Model> {
    c: fmi2Component,
    book: Box<LogBook>,
    vars: Vec<ScalarVariable<M::Var>>,
    saved: fmi2FMUstate,
    /// Value references and names of the Real outputs.
    out_vrs: Vec<u32>,
    pub out_names: Vec<&'static str>,
    iterations_vr: Option<u32>,
    /// Value references of the inputs `activation` and `length`.
    input_vrs: [u32; 2],
    _m: PhantomData<M>,
}

pub(crate) fn status_name(s: fmi2Status) -> &'static str {
    match s {
        fmi2OK => "fmi2OK",
        fmi2Warning => "fmi2Warning",
        fmi2Discard => "fmi2Discard",
        fmi2Error => "fmi2Error",
        fmi2Fatal => "fmi2Fatal",
        fmi2Pending => "fmi2Pending",
    }
}

impl<M: Model> Fmu<M> {
    pub fn new(name: &str) -> Result<Fmu<M>, String> {
        let book = Box::new(LogBook::default());
        let cb = callbacks(&book);
        let guid = CString::new(guid::<M>()).unwrap();
        let name = CString::new(name).unwrap();
        // SAFETY: valid C strings and callbacks; the book outlives the instance.
        let c = unsafe {
            api::instantiate::<M>(
                name.as_ptr(),
                fmi2CoSimulation,
                guid.as_ptr(),
                c"file:///tmp/".as_ptr(),
                &cb,
                fmi2False,
                fmi2False,
            )
        };
        if c.is_null() {
            return Err(format!("fmi2Instantiate failed: {:?}", book.take()));
        }
        let vars = M::variables();
        let outputs: Vec<u32> = (0..vars.len() as u32)
            .filter(|&i| {
                let v = &vars[i as usize];
                v.causality == Causality::Output && matches!(v.ty, VarType::Real { .. })
            })
            .collect();
        let iterations_vr = vars
            .iter()
            .position(|v| v.name == "newton_iterations" && matches!(v.ty, VarType::Integer { .. }))
            .map(|i| i as u32);
        let vr_of = |name: &str| {
            vars.iter()
                .position(|v| v.name == name && v.causality == Causality::Input)
                .map(|i| i as u32)
                .ok_or_else(|| format!("the model has no input {name}"))
        };
        let input_vrs = [vr_of("activation")?, vr_of("length")?];
        Ok(Fmu {
            input_vrs,
            c,
            out_names: outputs.iter().map(|&i| vars[i as usize].name).collect(),
            out_vrs: outputs,
            iterations_vr,
            vars,
            book,
            saved: null_mut(),
            _m: PhantomData,
        })
    }

    fn vr(&self, name: &str) -> Result<u32, String> {
        self.vars
            .iter()
            .position(|v| v.name == name)
            .map(|i| i as u32)
            .ok_or_else(|| format!("the model has no variable {name}"))
    }

    /// The status as a `Result`, with the messages logged by the call.
    fn check(&self, what: &str, st: fmi2Status) -> Result<fmi2Status, String> {
        let logs = self.book.take();
        if st == fmi2OK || st == fmi2Warning {
            Ok(st)
        } else {
            let msgs: Vec<String> = logs.into_iter().map(|e| e.message).collect();
            Err(format!("{what}: {}: {}", status_name(st), msgs.join(" | ")))
        }
    }

    pub fn set_integer(&mut self, name: &str, value: i32) -> Result<(), String> {
        let vr = self.vr(name)?;
        // SAFETY: live instance, one-element arrays.
        let st = unsafe { api::set_integer::<M>(self.c, &vr, 1, &value) };
        self.check(&format!("fmi2SetInteger({name} = {value})"), st)
            .map(|_| ())
    }

    pub fn set_boolean(&mut self, name: &str, value: bool) -> Result<(), String> {
        let vr = self.vr(name)?;
        let v = fmi2Boolean::from(value);
        // SAFETY: live instance, one-element arrays.
        let st = unsafe { api::set_boolean::<M>(self.c, &vr, 1, &v) };
        self.check(&format!("fmi2SetBoolean({name} = {value})"), st)
            .map(|_| ())
    }

    pub fn set_real(&mut self, name: &str, value: f64) -> Result<(), String> {
        let vr = self.vr(name)?;
        // SAFETY: live instance, one-element arrays.
        let st = unsafe { api::set_real::<M>(self.c, &vr, 1, &value) };
        self.check(&format!("fmi2SetReal({name} = {value})"), st)
            .map(|_| ())
    }

    /// Sets the activation command and the length in one fmi2SetReal.
    pub fn set_inputs(&mut self, command: f64, length: f64) -> Result<(), String> {
        let vals = [command, length];
        // SAFETY: live instance, two-element arrays.
        let st = unsafe { api::set_real::<M>(self.c, self.input_vrs.as_ptr(), 2, vals.as_ptr()) };
        self.check("fmi2SetReal(activation, length)", st)
            .map(|_| ())
    }

    pub fn initialize(&mut self) -> Result<(), String> {
        // SAFETY: live instance.
        let st = unsafe { api::setup_experiment::<M>(self.c, fmi2False, 0.0, 0.0, fmi2False, 0.0) };
        self.check("fmi2SetupExperiment", st)?;
        let st = unsafe { api::enter_initialization_mode::<M>(self.c) };
        self.check("fmi2EnterInitializationMode", st)?;
        let st = unsafe { api::exit_initialization_mode::<M>(self.c) };
        self.check("fmi2ExitInitializationMode", st).map(|_| ())
    }

    /// fmi2DoStep: the status and, unless fmi2OK, the messages logged.
    pub fn step(&mut self, t: f64, h: f64) -> (fmi2Status, String) {
        // SAFETY: live instance.
        let st = unsafe { api::do_step::<M>(self.c, t, h, fmi2True) };
        let logs = self.book.take();
        let msg = logs
            .into_iter()
            .map(|e| e.message)
            .collect::<Vec<_>>()
            .join(" | ");
        (st, msg)
    }

    /// fmi2GetReal of one variable by name.
    pub fn get_real(&self, name: &str) -> Result<f64, String> {
        let vr = self.vr(name)?;
        let mut v = f64::NAN;
        // SAFETY: live instance, one-element arrays.
        let st = unsafe { api::get_real::<M>(self.c, &vr, 1, &mut v) };
        self.check(&format!("fmi2GetReal({name})"), st).map(|_| v)
    }

    pub fn outputs(&self, into: &mut Vec<f64>) -> Result<(), String> {
        into.clear();
        into.resize(self.out_vrs.len(), f64::NAN);
        // SAFETY: live instance, arrays of the same length.
        let st = unsafe {
            api::get_real::<M>(
                self.c,
                self.out_vrs.as_ptr(),
                self.out_vrs.len(),
                into.as_mut_ptr(),
            )
        };
        self.check("fmi2GetReal(outputs)", st).map(|_| ())
    }

    pub fn save(&mut self) -> Result<(), String> {
        // SAFETY: live instance; `saved` NULL or a state of this instance.
        let st = unsafe { api::get_fmu_state::<M>(self.c, &mut self.saved) };
        self.check("fmi2GetFMUstate", st).map(|_| ())
    }

    pub fn restore(&mut self) -> Result<(), String> {
        // SAFETY: live instance; `saved` a state of this instance.
        let st = unsafe { api::set_fmu_state::<M>(self.c, self.saved) };
        self.check("fmi2SetFMUstate", st).map(|_| ())
    }

    pub fn last_successful_time(&self) -> Result<f64, String> {
        let mut t = f64::NAN;
        // SAFETY: live instance.
        let st = unsafe { api::get_real_status::<M>(self.c, fmi2LastSuccessfulTime, &mut t) };
        self.check("fmi2GetRealStatus(fmi2LastSuccessfulTime)", st)
            .map(|_| t)
    }

    /// The model's own serialized state (`Model::serialize`, without the FMI
    /// layer's state): read only, like [`Fmu::stats`], for a test that an
    /// instance is exactly as before.
    pub fn model_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        // SAFETY: live instance of `M`; read only, between FMI calls on
        // this thread.
        if let Some(inst) = unsafe { Instance::<M>::from_component(self.c) } {
            inst.model.serialize(&mut out);
        }
        out
    }

    pub fn stats(&self, hook: Option<fn(&M) -> StepStats>) -> StepStats {
        if let Some(f) = hook {
            // SAFETY: live instance of `M`; read only, between FMI calls on
            // this thread.
            if let Some(inst) = unsafe { Instance::<M>::from_component(self.c) } {
                return f(&inst.model);
            }
        }
        let mut s = StepStats::default();
        if let Some(vr) = self.iterations_vr {
            let mut n: fmi2Integer = 0;
            // SAFETY: live instance, one-element arrays.
            if unsafe { api::get_integer::<M>(self.c, &vr, 1, &mut n) } == fmi2OK {
                s.iterations = u32::try_from(n).ok();
            }
            self.book.take();
        }
        s
    }
}

impl<M: Model> Drop for Fmu<M> {
    fn drop(&mut self) {
        // SAFETY: live instance, freed exactly once (with its FMU states).
        unsafe { api::free_instance::<M>(self.c) };
    }
}
