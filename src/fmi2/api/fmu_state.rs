//! Getting, setting and serializing FMU states (FMI 2.0 spec, section 2.1.8).

use super::*;

fn known_state<'a, M: Model>(
    inst: &'a Instance<M>,
    func: &str,
    s: fmi2FMUstate,
) -> Result<&'a super::super::instance::Snapshot<M>, fmi2Status> {
    non_null(&inst.log, func, "FMUstate", s)?;
    inst.states.get(&(s as usize)).map(|b| &**b).ok_or_else(|| {
        inst.log.error(&format!(
            "{func}: FMUstate {s:p} is not an FMU state of this instance (freed, or from another instance)"
        ));
        fmi2Error
    })
}

fn register_state<M: Model>(
    inst: &mut Instance<M>,
    snap: super::super::instance::Snapshot<M>,
) -> fmi2FMUstate {
    let boxed = Box::new(snap);
    let key = &*boxed as *const super::super::instance::Snapshot<M> as usize;
    inst.states.insert(key, boxed);
    key as fmi2FMUstate
}

/// `fmi2GetFMUstate` (FMI 2.0 spec, section 2.1.8): a copy of the model and
/// of the layer state (FMI state, time, experiment setup, last successful
/// time, dirty flag). If `*FMUstate` is non-NULL it must be a state of this
/// instance, which is overwritten in place.
///
/// # Safety
/// `c` a live instance; `fmu_state` a valid `fmi2FMUstate*`.
pub unsafe fn get_fmu_state<M: Model>(
    c: fmi2Component,
    fmu_state: *mut fmi2FMUstate,
) -> fmi2Status {
    const F: &str = "fmi2GetFMUstate";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::FMU_STATE, |inst| {
            non_null(&inst.log, F, "FMUstate", fmu_state)?;
            let existing = *fmu_state;
            let snap = inst.snapshot();
            if existing.is_null() {
                *fmu_state = register_state(inst, snap);
            } else {
                known_state(inst, F, existing)?;
                if let Some(slot) = inst.states.get_mut(&(existing as usize)) {
                    **slot = snap;
                }
            }
            inst.log.debug(LogCategory::Events, || {
                format!(
                    "{F}: state {:p} saved at t = {:?}",
                    *fmu_state, inst.layer.time
                )
            });
            Ok(fmi2OK)
        })
    }
}

/// `fmi2SetFMUstate` (FMI 2.0 spec, section 2.1.8): restores model and layer
/// state exactly as saved, including the FMI state (so a state saved in
/// `stepComplete` brings an instance in `stepFailed` or `error` back to
/// `stepComplete`).
///
/// # Safety
/// `c` a live instance.
pub unsafe fn set_fmu_state<M: Model>(c: fmi2Component, fmu_state: fmi2FMUstate) -> fmi2Status {
    const F: &str = "fmi2SetFMUstate";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::FMU_STATE, |inst| {
            let snap = known_state(inst, F, fmu_state)?.clone();
            inst.model = snap.model;
            inst.layer = snap.layer;
            inst.log.debug(LogCategory::Events, || {
                format!(
                    "{F}: state {fmu_state:p} restored: {} at t = {:?}",
                    inst.layer.fmi_state.name(),
                    inst.layer.time
                )
            });
            Ok(fmi2OK)
        })
    }
}

/// `fmi2FreeFMUstate` (FMI 2.0 spec, section 2.1.8): frees `*FMUstate` and
/// sets it to NULL. A NULL `FMUstate` or `*FMUstate` is ignored.
///
/// # Safety
/// `c` a live instance; `fmu_state` NULL or a valid `fmi2FMUstate*`.
pub unsafe fn free_fmu_state<M: Model>(
    c: fmi2Component,
    fmu_state: *mut fmi2FMUstate,
) -> fmi2Status {
    const F: &str = "fmi2FreeFMUstate";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::FMU_STATE, |inst| {
            if fmu_state.is_null() || (*fmu_state).is_null() {
                return Ok(fmi2OK);
            }
            let s = *fmu_state;
            known_state(inst, F, s)?;
            inst.states.remove(&(s as usize));
            *fmu_state = std::ptr::null_mut();
            inst.log
                .debug(LogCategory::Events, || format!("{F}: state {s:p} freed"));
            Ok(fmi2OK)
        })
    }
}

/// `fmi2SerializedFMUstateSize` (FMI 2.0 spec, section 2.1.8).
///
/// # Safety
/// `c` a live instance; `size` a valid `size_t*`.
pub unsafe fn serialized_fmu_state_size<M: Model>(
    c: fmi2Component,
    fmu_state: fmi2FMUstate,
    size: *mut usize,
) -> fmi2Status {
    const F: &str = "fmi2SerializedFMUstateSize";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::FMU_STATE, |inst| {
            non_null(&inst.log, F, "size", size)?;
            let snap = known_state(inst, F, fmu_state)?;
            *size = encode_state(&inst.guid, snap).len();
            Ok(fmi2OK)
        })
    }
}

/// `fmi2SerializeFMUstate` (FMI 2.0 spec, section 2.1.8): writes the bytes
/// of [`encode_state`] (values, never pointers; restorable in another
/// process). `size` must be at least `fmi2SerializedFMUstateSize`; only that
/// many bytes are written.
///
/// # Safety
/// `c` a live instance; `serialized_state` `size` writable bytes.
pub unsafe fn serialize_fmu_state<M: Model>(
    c: fmi2Component,
    fmu_state: fmi2FMUstate,
    serialized_state: *mut fmi2Byte,
    size: usize,
) -> fmi2Status {
    const F: &str = "fmi2SerializeFMUstate";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::FMU_STATE, |inst| {
            let snap = known_state(inst, F, fmu_state)?;
            let bytes = encode_state(&inst.guid, snap);
            if size < bytes.len() {
                inst.log.error(&format!(
                    "{F}: buffer of {size} bytes is too small, {} bytes needed (fmi2SerializedFMUstateSize)",
                    bytes.len()
                ));
                return Err(fmi2Error);
            }
            let out = out_slice(&inst.log, F, "serializedState", serialized_state, size)?;
            for (o, b) in out.iter_mut().zip(&bytes) {
                *o = *b as fmi2Byte;
            }
            Ok(fmi2OK)
        })
    }
}

/// `fmi2DeSerializeFMUstate` (FMI 2.0 spec, section 2.1.8): checks the
/// bytes ([`decode_state`]: magic, format version, length, checksum, GUID,
/// model data) and on success stores a new FMU state of this instance in
/// `*FMUstate`. Invalid bytes give `fmi2Error` and allocate nothing.
///
/// # Safety
/// `c` a live instance; `serialized_state` `size` readable bytes;
/// `fmu_state` a valid `fmi2FMUstate*`.
pub unsafe fn deserialize_fmu_state<M: Model>(
    c: fmi2Component,
    serialized_state: *const fmi2Byte,
    size: usize,
    fmu_state: *mut fmi2FMUstate,
) -> fmi2Status {
    const F: &str = "fmi2DeSerializeFMUstate";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::FMU_STATE, |inst| {
            non_null(&inst.log, F, "FMUstate", fmu_state)?;
            let bytes = in_slice(&inst.log, F, "serializedState", serialized_state, size)?;
            let bytes: &[u8] = std::slice::from_raw_parts(bytes.as_ptr() as *const u8, bytes.len());
            let snap = decode_state::<M>(&inst.guid, bytes).map_err(|msg| {
                inst.log.error(&format!("{F}: {msg}"));
                fmi2Error
            })?;
            *fmu_state = register_state(inst, snap);
            inst.log.debug(LogCategory::Events, || {
                format!("{F}: state {:p} created from {size} bytes", *fmu_state)
            });
            Ok(fmi2OK)
        })
    }
}

// ---------------------------------------------------------------------------
// Partial derivatives (FMI 2.0 spec, section 2.1.9)
// ---------------------------------------------------------------------------
