//! Denormal numbers flushed to zero while a scene renders, in both engines.
//!
//! A decaying recursion (a filter, a resonator, a reverberation) approaching silence
//! passes through numbers below 2.2·10⁻³⁰⁸, which the processor handles a hundred
//! times slower than normal ones, and which are inaudible. While a renderer works,
//! the floating-point unit of its thread is set to flush such results to zero and to
//! read such inputs as zero (x86-64: MXCSR's FTZ and DAZ bits; AArch64: FPCR's FZ
//! bit), and set back as it was when the call returns, so a host's thread is left
//! as the host had it. The renderer's own worker threads keep the setting.
//! (Stateful kernels also flush their recursions below 10⁻³⁰ themselves.)

/// Sets flush-to-zero while it lives, then restores the previous mode.
pub(crate) struct FlushDenormals {
    #[cfg_attr(
        not(any(target_arch = "x86_64", target_arch = "aarch64")),
        allow(dead_code)
    )]
    previous: u64,
}

impl FlushDenormals {
    pub(crate) fn new() -> Self {
        let previous = mode::get();
        mode::set(previous | mode::FLUSH);
        FlushDenormals { previous }
    }

    /// Sets flush-to-zero for the rest of the thread's life (for the renderer's own
    /// worker threads).
    pub(crate) fn for_this_thread() {
        mode::set(mode::get() | mode::FLUSH);
    }
}

impl Drop for FlushDenormals {
    fn drop(&mut self) {
        mode::set(self.previous);
    }
}

#[cfg(target_arch = "x86_64")]
mod mode {
    /// MXCSR's flush-to-zero (bit 15) and denormals-are-zero (bit 6).
    pub const FLUSH: u64 = 0x8040;

    #[allow(deprecated)] // the intrinsics are the documented way without inline asm
    pub fn get() -> u64 {
        // SAFETY: reading MXCSR has no effect; SSE is part of x86-64.
        u64::from(unsafe { std::arch::x86_64::_mm_getcsr() })
    }

    #[allow(deprecated)]
    pub fn set(mode: u64) {
        // SAFETY: only the FTZ and DAZ bits are changed from a value read from MXCSR
        // (or restored to it); neither can fault.
        unsafe { std::arch::x86_64::_mm_setcsr(mode as u32) }
    }
}

#[cfg(target_arch = "aarch64")]
mod mode {
    /// FPCR's flush-to-zero bit (24).
    pub const FLUSH: u64 = 1 << 24;

    pub fn get() -> u64 {
        let fpcr: u64;
        // SAFETY: reading FPCR has no effect.
        unsafe { std::arch::asm!("mrs {}, fpcr", out(reg) fpcr, options(nomem, nostack)) };
        fpcr
    }

    pub fn set(mode: u64) {
        // SAFETY: only the FZ bit is changed from a value read from FPCR.
        unsafe { std::arch::asm!("msr fpcr, {}", in(reg) mode, options(nomem, nostack)) };
    }
}

#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
mod mode {
    pub const FLUSH: u64 = 0;
    pub fn get() -> u64 {
        0
    }
    pub fn set(_: u64) {}
}
