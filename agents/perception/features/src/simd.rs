//! Runtime detection of the vector units the hot row loops are compiled for.
//!
//! The workspace builds for baseline x86-64 (SSE2, 4 lanes); the row loops of the Hessian and the
//! local average are also compiled with AVX2 (8 lanes) and chosen per frame when the CPU has it.
//! Both versions run the same integer sums and the same float operations in the same order (no
//! FMA), so they give the same numbers bit for bit.

/// Whether the running CPU has AVX2 (cached by the standard library after the first call).
pub(crate) fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
