//! Which of the CPU's vector units run the hot kernels, chosen at run time.
//!
//! One wheel is built for baseline x86-64 (SSE2) and runs on every x86-64 machine. A hot kernel
//! is written once, as plain Rust over short arrays (one element a lane: the 8 rays of the IR
//! ring, ...), and compiled three times by [`multiversion!`]: for the baseline, for AVX2 and
//! for AVX-512. The first call picks the widest path this CPU has (or the one forced with
//! [`force`], `KHEPERA_GYM_SIMD` from Python); every call after reads it from one atomic.
//!
//! The paths give the same bits. Rust never fuses a multiply and an add (there is no
//! `-ffast-math` and no float contraction): add, multiply, divide, sqrt, min, max and compare
//! are IEEE operations whatever the width of the register they run in, and a loop over lanes
//! keeps each lane's order of operations. Transcendental functions (sin, cos, exp) are not in
//! the kernels: they stay calls to the one libm every path shares. `tests/test_simd_paths.py`
//! forces each path the machine has and replays every task's golden digest.
//!
//! aarch64 (and any other architecture) has the portable path only. It compiles there (`cargo
//! check --target aarch64-unknown-linux-gnu`), but no aarch64 machine or linker is at hand to
//! run it: unverified.

use std::sync::atomic::{AtomicU8, Ordering};

use crate::error::{Error, Result};

/// A set of vector units a kernel is compiled for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Path {
    /// The build's own target (SSE2 on x86-64): every machine.
    Portable = 0,
    /// AVX2 (x86-64, Haswell and Zen onward).
    Avx2 = 1,
    /// AVX-512 F, BW, DQ and VL (x86-64, Skylake-SP, Ice Lake and Zen 4 onward).
    Avx512 = 2,
}

/// Every path, narrowest first.
pub const PATHS: [Path; 3] = [Path::Portable, Path::Avx2, Path::Avx512];

/// Where a path is asked for, in errors: the variable the Python package reads it from.
const ORIGIN: &str = "KHEPERA_GYM_SIMD";
const UNCHOSEN: u8 = u8::MAX;
static CHOSEN: AtomicU8 = AtomicU8::new(UNCHOSEN);

impl Path {
    /// Its name: `portable`, `avx2` or `avx512`.
    pub fn name(self) -> &'static str {
        match self {
            Path::Portable => "portable",
            Path::Avx2 => "avx2",
            Path::Avx512 => "avx512",
        }
    }

    /// Whether this CPU has the units the path needs.
    pub fn available(self) -> bool {
        match self {
            Path::Portable => true,
            #[cfg(target_arch = "x86_64")]
            Path::Avx2 => std::arch::is_x86_feature_detected!("avx2"),
            #[cfg(target_arch = "x86_64")]
            Path::Avx512 => {
                std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512bw")
                    && std::arch::is_x86_feature_detected!("avx512dq")
                    && std::arch::is_x86_feature_detected!("avx512vl")
            }
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }

    /// The path named `name`.
    pub fn parse(name: &str) -> Result<Path> {
        PATHS.into_iter().find(|p| p.name() == name).ok_or_else(|| {
            let known: Vec<&str> = PATHS.iter().map(|p| p.name()).collect();
            Error::config(
                ORIGIN,
                "path",
                format!("unknown vector path {name:?}; known: {}", known.join(", ")),
            )
        })
    }
}

/// The widest path this CPU has.
pub fn widest() -> Path {
    PATHS
        .into_iter()
        .rev()
        .find(|p| p.available())
        .unwrap_or(Path::Portable)
}

/// The path the kernels run: the one forced, else the widest this CPU has.
#[inline]
pub fn path() -> Path {
    match CHOSEN.load(Ordering::Relaxed) {
        0 => Path::Portable,
        1 => Path::Avx2,
        2 => Path::Avx512,
        _ => {
            let best = widest();
            CHOSEN.store(best as u8, Ordering::Relaxed);
            best
        }
    }
}

/// Runs the kernels on `path` from now on, in every thread; an error when this CPU lacks it.
pub fn force(path: Path) -> Result<()> {
    if !path.available() {
        let have: Vec<&str> = PATHS
            .iter()
            .filter(|p| p.available())
            .map(|p| p.name())
            .collect();
        return Err(Error::config(
            ORIGIN,
            "path",
            format!(
                "this CPU has no {} units: the paths it has are {}",
                path.name(),
                have.join(", ")
            ),
        ));
    }
    CHOSEN.store(path as u8, Ordering::Relaxed);
    Ok(())
}

/// Compiles a kernel once for each [`Path`] and calls the one [`path`] chooses.
///
/// `multiversion!(fn name(args) -> T = body_fn);` defines `name`, which calls `body_fn` (an
/// `#[inline(always)]` function holding the kernel) inlined into a copy compiled with the
/// path's target features. `multiversion!(fn name(args) -> T = body_fn, portable = other_fn);`
/// runs `other_fn` on the portable path instead: where lanes pay only in wide registers, the
/// narrow path keeps the scalar code (which the lanes must match bit for bit).
#[macro_export]
macro_rules! multiversion {
    ($(#[$meta:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? = $body:path;) => {
        $crate::multiversion! {
            $(#[$meta])* $vis fn $name($($arg: $ty),*) $(-> $ret)? = $body, portable = $body;
        }
    };
    ($(#[$meta:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? = $body:path, portable = $portable:path;) => {
        $(#[$meta])*
        #[inline]
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2")]
                fn avx2($($arg: $ty),*) $(-> $ret)? {
                    $body($($arg),*)
                }
                #[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl,avx2")]
                fn avx512($($arg: $ty),*) $(-> $ret)? {
                    $body($($arg),*)
                }
                match $crate::simd::path() {
                    // SAFETY: `path` returns a path only when this CPU has its units.
                    $crate::simd::Path::Avx512 => return unsafe { avx512($($arg),*) },
                    $crate::simd::Path::Avx2 => return unsafe { avx2($($arg),*) },
                    $crate::simd::Path::Portable => {}
                }
            }
            $portable($($arg),*)
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[inline(always)]
    fn lanes_body(a: &[f32; 8], b: &[f32; 8]) -> [f32; 8] {
        let mut out = [0.0; 8];
        for k in 0..8 {
            out[k] = (a[k] * b[k] + a[k] / b[k]).sqrt().min(b[k]);
        }
        out
    }

    crate::multiversion! {
        fn lanes(a: &[f32; 8], b: &[f32; 8]) -> [f32; 8] = lanes_body;
    }

    #[test]
    fn every_path_the_cpu_has_gives_the_portable_bits_and_others_are_refused() {
        let a = [0.3, -1.0, 2.5, f32::NAN, 1e-30, 7.0, 0.0, -0.0];
        let b = [1.7, 3.0, -0.5, 1.0, 1e30, f32::INFINITY, 2.0, 5.0];
        force(Path::Portable).expect("portable is everywhere");
        let want = lanes(&a, &b).map(f32::to_bits);
        for p in PATHS {
            if p.available() {
                force(p).expect("available");
                assert_eq!(path(), p);
                assert_eq!(lanes(&a, &b).map(f32::to_bits), want, "{}", p.name());
            } else {
                let e = force(p).unwrap_err().to_string();
                assert!(e.contains(p.name()) && e.contains("portable"), "{e}");
            }
        }
        force(widest()).expect("the widest");
        let e = Path::parse("avx9").unwrap_err().to_string();
        assert!(e.contains("portable, avx2, avx512"), "{e}");
    }
}
