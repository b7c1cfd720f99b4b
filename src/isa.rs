//! Which SIMD instruction set a kernel runs with: the target's baseline, or AVX2 when the running
//! CPU reports it (checked once per call of [`Isa::avx2`]). Used by the batched dynamics kernels
//! (`dynamics::batch`, docs/batch.md §3) and the sparse surrogates' dense bilinear part
//! (`uq::sparse_surrogate`). A ground-floor module: it imports nothing from the crate.
//!
//! Does not: hold kernels (each kernel matches on `Isa::kind` itself).

/// Which instruction set a vectorised kernel is compiled for. Only [`Isa::baseline`] and, when the
/// running CPU reports AVX2, [`Isa::avx2`] can be made, so a kernel never runs instructions the
/// CPU lacks. Results are bitwise the same with either (IEEE operations are exact per lane and
/// neither contracts into FMA).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Isa(IsaKind);

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum IsaKind {
    Baseline,
    #[cfg(target_arch = "x86_64")]
    Avx2,
}

impl Isa {
    /// The target's baseline (SSE2 on x86-64: 2 `f64` per vector instruction).
    pub fn baseline() -> Self {
        Isa(IsaKind::Baseline)
    }

    /// AVX2 (4 `f64` per vector instruction, no FMA), if this CPU has it.
    pub fn avx2() -> Option<Self> {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            return Some(Isa(IsaKind::Avx2));
        }
        None
    }

    /// The fastest available: [`Isa::avx2`] if the CPU has it, else [`Isa::baseline`].
    pub fn best() -> Self {
        Self::avx2().unwrap_or_else(Self::baseline)
    }

    /// A short name (`"baseline"`, `"avx2"`) for reports.
    pub fn name(&self) -> &'static str {
        match self.0 {
            IsaKind::Baseline => "baseline",
            #[cfg(target_arch = "x86_64")]
            IsaKind::Avx2 => "avx2",
        }
    }

    pub(crate) fn kind(&self) -> IsaKind {
        self.0
    }
}
