//! Whether this CPU runs the instructions the build was compiled for.
//!
//! The release build targets x86-64-v3 (AVX2 and FMA; see `.cargo/config.toml`), so the kernel's
//! four-wide SIMD compiles to AVX2. On an older CPU the first such instruction would kill the
//! process with SIGILL. Programs ask [`missing_features`] before they compute anything and stop
//! with its message; a library host (an FMU's instantiate) returns it as an error instead.

/// `None` when this CPU has every instruction set the build targets; otherwise what is missing
/// and how to rebuild for this CPU.
pub fn missing_features() -> Option<String> {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    if !std::arch::is_x86_feature_detected!("avx2") || !std::arch::is_x86_feature_detected!("fma") {
        return Some(
            "this build targets x86-64-v3 (AVX2) but the CPU lacks it; \
             rebuild without .cargo/config.toml's target-cpu setting"
                .to_string(),
        );
    }
    None
}
