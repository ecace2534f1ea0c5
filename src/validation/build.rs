//! What a validation record states about the software's build and the machine.

use serde::Serialize;

/// How this binary was built (from the build script, `build.rs`).
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct BuildInfo {
    /// The git commit it was built from (HEAD when it was built; changes not committed
    /// are not seen), or `unknown` outside a git work tree.
    pub commit: &'static str,
    /// `rustc --version` of the compiler.
    pub compiler: &'static str,
    /// The target triple.
    pub target: &'static str,
    /// Cargo's profile (`release`, `debug`).
    pub profile: &'static str,
    /// The crate's features enabled, in name order.
    pub features: Vec<&'static str>,
}

impl BuildInfo {
    /// This build's.
    pub fn of_this_build() -> BuildInfo {
        BuildInfo {
            commit: env!("POLYCAL_BUILD_COMMIT"),
            compiler: env!("POLYCAL_BUILD_RUSTC"),
            target: env!("POLYCAL_BUILD_TARGET"),
            profile: env!("POLYCAL_BUILD_PROFILE"),
            features: env!("POLYCAL_BUILD_FEATURES")
                .split(',')
                .filter(|f| !f.is_empty())
                .collect(),
        }
    }
}

/// The machine the validation ran on.
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct Platform {
    /// The operating system (`linux`, `macos`, `windows`, …).
    pub os: &'static str,
    /// The processor architecture (`x86_64`, `aarch64`, …).
    pub arch: &'static str,
    /// The threads available to the process.
    pub threads: usize,
}

impl Platform {
    /// This machine's.
    pub fn of_this_machine() -> Platform {
        Platform {
            os: std::env::consts::OS,
            arch: std::env::consts::ARCH,
            threads: std::thread::available_parallelism().map_or(1, usize::from),
        }
    }
}
