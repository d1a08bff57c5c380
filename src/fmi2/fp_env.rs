//! The floating-point environment around every FMI entry point.
//!
//! A host may run with floating-point exceptions trapping (SIGFPE on an
//! overflow, a division by zero or an invalid operation), with flush-to-zero
//! or with another rounding mode. The FMU's numerics assume the default IEEE
//! environment: they overflow to ±∞ and divide by zero on legal inputs and
//! test the result (a step that overflows is discarded, not trapped). So each
//! entry point holds a [`QuietFp`] for its whole call: when the caller's
//! environment differs from the default — any exception unmasked, a rounding
//! mode other than to-nearest, flush-to-zero or denormals-are-zero — it is
//! saved, the default is set, and the caller's is restored on return (on
//! x87, with the exception flags the call raised cleared first, so that no
//! trap is left pending for the caller). In the default environment, the
//! usual case, the cost is one read of each control register.
//!
//! Implemented for x86_64 (SSE's MXCSR and the x87 control word) and aarch64
//! (FPCR); on other targets the caller's environment is used as it is.

/// Guard of the default floating-point environment (module docs): created at
/// the start of an entry point, restores the caller's environment when
/// dropped.
#[must_use]
pub struct QuietFp {
    saved: Option<arch::Saved>,
}

impl QuietFp {
    /// Set the default environment if the caller's differs from it.
    #[inline]
    pub fn enter() -> QuietFp {
        QuietFp {
            saved: arch::hold(),
        }
    }
}

impl Drop for QuietFp {
    #[inline]
    fn drop(&mut self) {
        if let Some(saved) = &self.saved {
            arch::restore(saved);
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod arch {
    use std::arch::asm;

    /// MXCSR of the default environment: every exception masked, flags
    /// clear, round to nearest, no flush-to-zero or denormals-are-zero.
    const DEFAULT_MXCSR: u32 = 0x1F80;
    /// MXCSR bits that are not exception flags (bits 0–5).
    const MXCSR_CONTROL: u32 = !0x3F;
    /// x87 control word bits of the exception masks (bits 0–5).
    const X87_MASKS: u16 = 0x3F;

    /// The caller's control registers.
    pub struct Saved {
        mxcsr: u32,
        x87: u16,
    }

    fn mxcsr() -> u32 {
        let mut v: u32 = 0;
        // SAFETY: stores MXCSR into a local.
        unsafe { asm!("stmxcsr [{}]", in(reg) &mut v, options(nostack, preserves_flags)) };
        v
    }

    fn set_mxcsr(v: u32) {
        // SAFETY: loads a valid MXCSR value (reserved bits 16–31 zero).
        unsafe { asm!("ldmxcsr [{}]", in(reg) &v, options(nostack, readonly, preserves_flags)) };
    }

    fn x87_control() -> u16 {
        let mut v: u16 = 0;
        // SAFETY: stores the x87 control word into a local.
        unsafe { asm!("fnstcw [{}]", in(reg) &mut v, options(nostack, preserves_flags)) };
        v
    }

    fn set_x87_control(v: u16) {
        // SAFETY: clears the x87 exception flags (so unmasking cannot leave a
        // trap pending), then loads a control word the caller had.
        unsafe {
            asm!("fnclex", options(nomem, nostack, preserves_flags));
            asm!("fldcw [{}]", in(reg) &v, options(nostack, readonly, preserves_flags));
        }
    }

    #[inline]
    pub fn hold() -> Option<Saved> {
        let (mxcsr, x87) = (mxcsr(), x87_control());
        let default_sse = mxcsr & MXCSR_CONTROL == DEFAULT_MXCSR;
        let masked_x87 = x87 & X87_MASKS == X87_MASKS;
        if default_sse && masked_x87 {
            return None;
        }
        set_mxcsr(DEFAULT_MXCSR);
        if !masked_x87 {
            set_x87_control(x87 | X87_MASKS);
        }
        Some(Saved { mxcsr, x87 })
    }

    #[inline]
    pub fn restore(saved: &Saved) {
        set_mxcsr(saved.mxcsr);
        if saved.x87 & X87_MASKS != X87_MASKS {
            set_x87_control(saved.x87);
        }
    }
}

#[cfg(target_arch = "aarch64")]
mod arch {
    use std::arch::asm;

    /// FPCR bits that differ from the default environment: the trap enables
    /// (IOE, DZE, OFE, UFE, IXE, IDE: bits 8–12 and 15), flush-to-zero
    /// (bit 24), default NaN (bit 25) and the rounding mode (bits 22–23).
    const NON_DEFAULT: u64 = 0x1F00 | 0x8000 | (1 << 24) | (1 << 25) | (3 << 22);

    pub struct Saved {
        fpcr: u64,
    }

    fn fpcr() -> u64 {
        let v: u64;
        // SAFETY: reads FPCR.
        unsafe { asm!("mrs {}, fpcr", out(reg) v, options(nomem, nostack, preserves_flags)) };
        v
    }

    fn set_fpcr(v: u64) {
        // SAFETY: writes an FPCR value derived from the current one.
        unsafe { asm!("msr fpcr, {}", in(reg) v, options(nomem, nostack, preserves_flags)) };
    }

    #[inline]
    pub fn hold() -> Option<Saved> {
        let fpcr = fpcr();
        if fpcr & NON_DEFAULT == 0 {
            return None;
        }
        set_fpcr(fpcr & !NON_DEFAULT);
        Some(Saved { fpcr })
    }

    #[inline]
    pub fn restore(saved: &Saved) {
        set_fpcr(saved.fpcr);
    }
}

#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
mod arch {
    pub struct Saved;

    #[inline]
    pub fn hold() -> Option<Saved> {
        None
    }

    #[inline]
    pub fn restore(_: &Saved) {}
}

/// Test support: run `f` with the overflow, division-by-zero and invalid
/// exceptions trapping (SSE and x87), then restore the default environment.
/// Returns `f`'s result and whether the environment after `f` was still the
/// trapping one (an entry point must give the caller its environment back).
#[cfg(target_arch = "x86_64")]
pub fn with_traps<T>(f: impl FnOnce() -> T) -> (T, bool) {
    use std::arch::asm;
    // Unmask invalid (bit 0), divide-by-zero (bit 2) and overflow (bit 3).
    let trapping_sse: u32 = 0x1F80 & !((1 << 7) | (1 << 9) | (1 << 10));
    let trapping_x87: u16 = 0x037F & !(1 | (1 << 2) | (1 << 3));
    let read = || {
        let (mut m, mut c): (u32, u16) = (0, 0);
        // SAFETY: stores the control registers into locals.
        unsafe {
            asm!("stmxcsr [{}]", in(reg) &mut m, options(nostack));
            asm!("fnstcw [{}]", in(reg) &mut c, options(nostack));
        }
        (m & !0x3F, c)
    };
    let set = |m: u32, c: u16| {
        // SAFETY: valid control values; flags cleared before unmasking.
        unsafe {
            asm!("fnclex", options(nomem, nostack));
            asm!("fldcw [{}]", in(reg) &c, options(nostack, readonly));
            asm!("ldmxcsr [{}]", in(reg) &m, options(nostack, readonly));
        }
    };
    set(trapping_sse, trapping_x87);
    let out = f();
    let after = read();
    set(0x1F80, 0x037F);
    (out, after == (trapping_sse, trapping_x87))
}
