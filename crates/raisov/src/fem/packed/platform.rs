//! What the packed force pass asks of the machine: the instruction set of its kernels
//! ([`Isa`], with the `RAISOV_ISA` override), the size of the last-level cache (for the row
//! prefetch rule) and transparent huge pages for its large arrays.
//!
//! Nothing here changes a result: every [`Isa`] gives the same bits, and the cache size and
//! huge pages only decide prefetching and page size.

/// Instruction set of the packed kernels, narrowest first (so that `min` caps a choice).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Isa {
    /// The lane loops of [`super::portable`], on any CPU.
    Portable,
    /// AVX2 + FMA, 4 lanes ([`super::x86`]).
    Avx2,
    /// AVX-512F (with AVX2 + FMA): the positions kernel in 8 lanes, two groups side by side.
    Avx512,
}

impl Isa {
    /// `"portable"`, `"avx2"` or `"avx512"`: the values of `RAISOV_ISA` and the name in the
    /// benchmark table.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Isa::Portable => "portable",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }

    /// Inverse of [`Isa::name`].
    fn from_name(s: &str) -> Option<Isa> {
        [Isa::Portable, Isa::Avx2, Isa::Avx512]
            .into_iter()
            .find(|i| i.name() == s)
    }

    /// The kernel to run: [`Isa::Avx512`] where 512-bit vectors pay, else [`Isa::Avx2`] with
    /// AVX2 + FMA, else [`Isa::Portable`], never wider than [`Isa::supported`].
    /// `RAISOV_ISA=portable`, `avx2` or `avx512` caps the choice, or forces AVX-512 where it
    /// was left out (for comparisons); all give the same bits. AVX-512 is left out on AMD
    /// family 19h (Zen 3 and 4), which executes a 512-bit operation as two 256-bit halves, so
    /// that the 8-lane kernel has nothing over the 4-lane one there.
    pub(crate) fn detect() -> Isa {
        #[cfg(target_arch = "x86_64")]
        let wide_pays = !half_width_512();
        #[cfg(not(target_arch = "x86_64"))]
        let wide_pays = false;
        let default = if wide_pays { Isa::Avx512 } else { Isa::Avx2 };
        let cap = std::env::var("RAISOV_ISA")
            .ok()
            .and_then(|s| Isa::from_name(&s))
            .unwrap_or(default);
        Isa::supported().min(cap)
    }

    /// The widest kernel this CPU can run: [`Isa::Avx512`] with AVX-512F (and AVX2 + FMA),
    /// [`Isa::Avx2`] with AVX2 + FMA, else [`Isa::Portable`].
    pub(crate) fn supported() -> Isa {
        #[cfg(target_arch = "x86_64")]
        {
            let avx2 =
                std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma");
            if avx2 && std::is_x86_feature_detected!("avx512f") {
                Isa::Avx512
            } else if avx2 {
                Isa::Avx2
            } else {
                Isa::Portable
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        Isa::Portable
    }
}

/// Whether this is an AMD family 19h CPU (Zen 3, Zen 4), whose 512-bit operations run as
/// two 256-bit halves.
#[cfg(target_arch = "x86_64")]
fn half_width_512() -> bool {
    use std::arch::x86_64::__cpuid;
    #[allow(unused_unsafe)]
    // SAFETY: `cpuid` exists on every x86-64 CPU.
    let (v, f) = unsafe { (__cpuid(0), __cpuid(1).eax) };
    let amd = (v.ebx, v.edx, v.ecx) == (0x6874_7541, 0x6974_6e65, 0x444d_4163);
    let family = ((f >> 8) & 0xf)
        + if (f >> 8) & 0xf == 0xf {
            (f >> 20) & 0xff
        } else {
            0
        };
    amd && family == 0x19
}

/// Size of the last-level cache (bytes): Linux's `cpu0/cache/index3/size`, else 32 MiB.
pub(super) fn l3_bytes() -> usize {
    static L3: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *L3.get_or_init(|| {
        std::fs::read_to_string("/sys/devices/system/cpu/cpu0/cache/index3/size")
            .ok()
            .and_then(|t| {
                let t = t.trim();
                let (num, mul) = match t.chars().last()? {
                    'K' => (&t[..t.len() - 1], 1 << 10),
                    'M' => (&t[..t.len() - 1], 1 << 20),
                    _ => (t, 1),
                };
                num.parse::<usize>().ok().map(|n| n * mul)
            })
            .filter(|&b| b > 0)
            .unwrap_or(32 << 20)
    })
}

/// An empty vector with room for `n` elements whose memory, if large, is advised for
/// transparent huge pages before anything touches it (Linux `madvise(MADV_HUGEPAGE)`; a
/// no-op elsewhere, where THP is off, or on failure). The force pass streams the element
/// data and the node rows once per step; with 4 KiB pages every 64 lines of a stream cost a
/// TLB miss, and each row prefetch a page walk.
pub(crate) fn huge_page_vec<T>(n: usize) -> Vec<T> {
    let v: Vec<T> = Vec::with_capacity(n);
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        let bytes = n * std::mem::size_of::<T>();
        if bytes >= 2 * HUGE {
            let start = (v.as_ptr() as usize).next_multiple_of(4096);
            let end = (v.as_ptr() as usize + bytes) & !4095;
            if end > start {
                // SAFETY: advice on pages of this vector's own allocation; it changes no
                // contents and its failure is harmless.
                unsafe {
                    libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
                }
            }
        }
    }
    v
}
