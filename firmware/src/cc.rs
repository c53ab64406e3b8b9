//! Compiling the C backend's output with real C compilers for the Cortex-M0+ (RP2040) into
//! an ELF executable the emulator loads.
//!
//! Each `.c` file is compiled with
//! `clang --target=thumbv6m-none-eabi -mcpu=cortex-m0plus -O2 -ffreestanding -fno-builtin`
//! or `arm-none-eabi-gcc -mcpu=cortex-m0plus -mthumb -O2 -ffreestanding` (both with `-std=c99
//! -ffunction-sections -fdata-sections -c`, so the linker can drop what the update does not
//! use), then linked by `arm-none-eabi-ld` with a generated linker script that places
//! everything in SRAM from 0x2000_0000, plus `libgcc.a` (found with `arm-none-eabi-gcc
//! -mcpu=cortex-m0plus -mthumb -print-libgcc-file-name`) for the `__aeabi_*` helpers the
//! compilers call (64-bit multiplies, divisions) and, when installed, newlib's `libc.a` for a
//! `memset`/`memcpy` a compiler may emit (none of the shipped instruments needs it). There is no startup code: the host calls
//! the functions (see [`crate::runner`]).
//!
//! Sizes: [`Build::update_bytes`] is the update's ELF symbol size; the update is also linked
//! alone (entry = update, `--gc-sections`), and [`Build::update_with_helpers_bytes`] is the
//! size of all code in that image: the update, the static functions the compiler did not
//! inline, and the library helpers it pulls in ([`Build::helpers`] lists them).

use object::{Object, ObjectSection, ObjectSymbol, SectionFlags, SymbolKind};
use std::fmt;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};
use tactus_compiler::cgen::CSource;

/// Where the linker script places the image (the start of the RP2040's striped SRAM).
pub const LOAD_ADDR: u32 = 0x2000_0000;

/// A C compiler for the Cortex-M0+.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Compiler {
    /// `clang --target=thumbv6m-none-eabi -mcpu=cortex-m0plus` (Debian package `clang`).
    Clang,
    /// `arm-none-eabi-gcc -mcpu=cortex-m0plus -mthumb` (Debian package `gcc-arm-none-eabi`).
    Gcc,
}

impl Compiler {
    /// Both compilers, clang first.
    pub const ALL: [Compiler; 2] = [Compiler::Clang, Compiler::Gcc];

    /// Short name for tables (`"clang"`, `"gcc"`).
    pub fn name(self) -> &'static str {
        match self {
            Compiler::Clang => "clang",
            Compiler::Gcc => "gcc",
        }
    }

    /// The executable.
    pub fn tool(self) -> &'static str {
        match self {
            Compiler::Clang => "clang",
            Compiler::Gcc => "arm-none-eabi-gcc",
        }
    }

    /// The flags selecting the target and the freestanding environment (without `-O`).
    pub fn target_flags(self) -> &'static [&'static str] {
        match self {
            Compiler::Clang => &[
                "--target=thumbv6m-none-eabi",
                "-mcpu=cortex-m0plus",
                "-ffreestanding",
                "-fno-builtin",
            ],
            Compiler::Gcc => &["-mcpu=cortex-m0plus", "-mthumb", "-ffreestanding"],
        }
    }

    /// The first line of `<tool> --version`.
    ///
    /// Errors: [`CcError::ToolMissing`] when the tool cannot be run.
    pub fn version(self) -> Result<String, CcError> {
        let out = run(Command::new(self.tool()).arg("--version"), self.tool())?;
        Ok(out.lines().next().unwrap_or("").trim().to_string())
    }
}

/// The Debian package that provides `tool` (for error messages).
pub fn package_of(tool: &str) -> &'static str {
    match tool {
        "clang" => "clang",
        "arm-none-eabi-gcc" => "gcc-arm-none-eabi",
        t if t.starts_with("arm-none-eabi-") => "binutils-arm-none-eabi",
        _ => "?",
    }
}

/// Why a build failed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CcError {
    /// A tool is not installed (or cannot be run).
    ToolMissing {
        /// The executable.
        tool: String,
        /// The Debian package providing it.
        package: String,
    },
    /// A tool ran and failed.
    Failed {
        /// The command line.
        command: String,
        /// What it printed on stderr.
        stderr: String,
    },
    /// A file in the work directory could not be written or read.
    Io(String),
    /// The linked ELF lacks something expected (a symbol) or cannot be parsed.
    BadOutput(String),
}

impl fmt::Display for CcError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CcError::ToolMissing { tool, package } => write!(
                f,
                "`{tool}` is not installed (Debian: apt-get install {package})"
            ),
            CcError::Failed { command, stderr } => write!(f, "`{command}` failed:\n{stderr}"),
            CcError::Io(e) => write!(f, "{e}"),
            CcError::BadOutput(e) => write!(f, "unexpected linker output: {e}"),
        }
    }
}

impl std::error::Error for CcError {}

/// Runs a command; its stdout on success.
fn run(cmd: &mut Command, tool: &str) -> Result<String, CcError> {
    let line = format!("{cmd:?}").replace('"', "");
    match cmd.output() {
        Err(_) => Err(CcError::ToolMissing {
            tool: tool.to_string(),
            package: package_of(tool).to_string(),
        }),
        Ok(o) if !o.status.success() => Err(CcError::Failed {
            command: line,
            stderr: String::from_utf8_lossy(&o.stderr).into_owned(),
        }),
        Ok(o) => Ok(String::from_utf8_lossy(&o.stdout).into_owned()),
    }
}

/// Checks that every tool a build with `compiler` needs can be run (the compiler,
/// `arm-none-eabi-gcc` for libgcc, `arm-none-eabi-ld`).
///
/// Errors: [`CcError::ToolMissing`] naming the first missing tool and its package.
pub fn check_tools(compiler: Compiler) -> Result<(), CcError> {
    compiler.version()?;
    Compiler::Gcc.version()?;
    run(
        Command::new("arm-none-eabi-ld").arg("--version"),
        "arm-none-eabi-ld",
    )?;
    Ok(())
}

/// Options of a build.
#[derive(Clone, Debug)]
pub struct Options {
    /// The optimisation flag (default `-O2`).
    pub opt: String,
    /// Further C files compiled and linked with the program, as (file name, text); they can
    /// `#include "<stem>.h"`. Their non-static symbols are kept (`-u` is not needed: they
    /// are linked into the full image only when referenced, so name them in `keep`).
    pub extra_sources: Vec<(String, String)>,
    /// Further symbols to keep in the full image (e.g. data defined in `extra_sources`).
    pub keep: Vec<String>,
    /// Where to put the work directory. `None`: the system temp dir, and the directory is
    /// removed after a successful build (left for inspection after a failure). `Some(dir)`:
    /// the directory `dir/tactus-cc-…-<stem>-<compiler>` is kept (sources, objects, the
    /// linker script, `full.elf` and `update.elf`).
    pub work_dir: Option<PathBuf>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            opt: "-O2".to_string(),
            extra_sources: Vec::new(),
            keep: Vec::new(),
            work_dir: None,
        }
    }
}

/// A function linked into the update-only image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Function {
    /// Symbol name; aliases at the same address joined by `=` (`__aeabi_lmul=__muldi3`).
    pub name: String,
    /// ELF symbol size, bytes.
    pub size: u32,
}

/// A linked executable and its code sizes.
#[derive(Clone, Debug)]
pub struct Build {
    /// Which compiler.
    pub compiler: Compiler,
    /// Its version line.
    pub version: String,
    /// The ELF executable (init, update and helpers; everything in SRAM from [`LOAD_ADDR`]).
    pub elf: Vec<u8>,
    /// ELF symbol size of `tactus_<stem>_update`, bytes.
    pub update_bytes: u32,
    /// All code linked when the update is the only root: the update, non-inlined static
    /// functions and library helpers, bytes (the size of the executable sections, alignment
    /// padding included).
    pub update_with_helpers_bytes: u32,
    /// Read-only data linked for the update alone (tables, constants), bytes.
    pub update_rodata_bytes: u32,
    /// The functions in the update-only image other than the update itself.
    pub helpers: Vec<Function>,
}

static BUILD_ID: AtomicUsize = AtomicUsize::new(0);

fn linker_script() -> String {
    format!(
        "/* Everything in SRAM; no startup code (the host calls the functions). */
SECTIONS
{{
    . = {LOAD_ADDR:#010x};
    .text : {{ *(.text .text.*) }}
    .rodata : ALIGN(4) {{ *(.rodata .rodata.*) }}
    .data : ALIGN(4) {{ *(.data .data.*) }}
    .bss : ALIGN(4) {{ *(.bss .bss.* COMMON) }}
    /DISCARD/ : {{ *(.ARM.exidx*) *(.ARM.extab*) *(.comment) }}
}}
"
    )
}

fn write(path: &Path, text: &str) -> Result<(), CcError> {
    std::fs::write(path, text).map_err(|e| CcError::Io(format!("{}: {e}", path.display())))
}

/// Compiles `c` (and `opts.extra_sources`) with `compiler` for the Cortex-M0+ and links an
/// ELF executable placed in SRAM from [`LOAD_ADDR`], with `tactus_<stem>_init` and
/// `tactus_<stem>_update` (and `opts.keep`) kept.
///
/// Errors: [`CcError::ToolMissing`] when the compiler, `arm-none-eabi-gcc` (for libgcc) or
/// `arm-none-eabi-ld` is not installed; [`CcError::Failed`] when a tool fails (its stderr
/// included); [`CcError::Io`]; [`CcError::BadOutput`] when the linked ELF has no update
/// symbol.
pub fn build(c: &CSource, compiler: Compiler, opts: &Options) -> Result<Build, CcError> {
    let version = compiler.version()?;
    let libgcc = run(
        Command::new("arm-none-eabi-gcc").args([
            "-mcpu=cortex-m0plus",
            "-mthumb",
            "-print-libgcc-file-name",
        ]),
        "arm-none-eabi-gcc",
    )?
    .trim()
    .to_string();
    let libc = run(
        Command::new("arm-none-eabi-gcc").args([
            "-mcpu=cortex-m0plus",
            "-mthumb",
            "-print-file-name=libc.a",
        ]),
        "arm-none-eabi-gcc",
    )?
    .trim()
    .to_string();
    let base = opts.work_dir.clone().unwrap_or_else(std::env::temp_dir);
    let dir = base.join(format!(
        "tactus-cc-{}-{}-{}-{}",
        std::process::id(),
        BUILD_ID.fetch_add(1, Ordering::Relaxed),
        c.stem,
        compiler.name()
    ));
    std::fs::create_dir_all(&dir).map_err(|e| CcError::Io(format!("{}: {e}", dir.display())))?;
    write(&dir.join(format!("{}.h", c.stem)), &c.header)?;
    let mut sources = vec![(format!("{}.c", c.stem), c.source.clone())];
    sources.extend(opts.extra_sources.iter().cloned());
    let mut objects = Vec::new();
    for (name, text) in &sources {
        let src = dir.join(name);
        write(&src, text)?;
        let obj = src.with_extension("o");
        run(
            Command::new(compiler.tool())
                .args(compiler.target_flags())
                .arg(&opts.opt)
                .args(["-std=c99", "-ffunction-sections", "-fdata-sections", "-c"])
                .arg("-I")
                .arg(&dir)
                .arg("-o")
                .arg(&obj)
                .arg(&src),
            compiler.tool(),
        )?;
        objects.push(obj);
    }
    let script = dir.join("sram.ld");
    write(&script, &linker_script())?;
    let init = tactus_compiler::abi::init_symbol(&c.stem);
    let update = tactus_compiler::abi::update_symbol(&c.stem);
    let link = |out: &Path, keep: &[&str]| -> Result<Vec<u8>, CcError> {
        let mut cmd = Command::new("arm-none-eabi-ld");
        cmd.arg("-T")
            .arg(&script)
            .args(["--gc-sections", "-e", &update]);
        for k in keep {
            cmd.arg("-u").arg(k);
        }
        cmd.arg("-o").arg(out).args(&objects);
        cmd.arg("--start-group").arg(&libgcc);
        // newlib (Debian: libnewlib-arm-none-eabi, only recommended by gcc-arm-none-eabi)
        // for a `memset`/`memcpy` a compiler may emit; without it, only libgcc.
        if Path::new(&libc).is_absolute() {
            cmd.arg(&libc);
        }
        cmd.arg("--end-group");
        run(&mut cmd, "arm-none-eabi-ld")?;
        std::fs::read(out).map_err(|e| CcError::Io(format!("{}: {e}", out.display())))
    };
    let mut keep: Vec<&str> = vec![&init];
    keep.extend(opts.keep.iter().map(|s| s.as_str()));
    let elf = link(&dir.join("full.elf"), &keep)?;
    let alone = link(&dir.join("update.elf"), &[])?;
    let (update_bytes, _) = sizes(&elf, &update)?;
    let (_, (text, rodata, funcs)) = sizes(&alone, &update)?;
    if opts.work_dir.is_none() {
        let _ = std::fs::remove_dir_all(&dir);
    }
    Ok(Build {
        compiler,
        version,
        elf,
        update_bytes,
        update_with_helpers_bytes: text,
        update_rodata_bytes: rodata,
        helpers: funcs
            .into_iter()
            .filter(|f| !f.name.split('=').any(|n| n == update))
            .collect(),
    })
}

/// The size of symbol `name`, and (executable bytes, read-only allocated data bytes, function
/// symbols) of an ELF file.
#[allow(clippy::type_complexity)]
fn sizes(elf: &[u8], name: &str) -> Result<(u32, (u32, u32, Vec<Function>)), CcError> {
    let file = object::File::parse(elf).map_err(|e| CcError::BadOutput(e.to_string()))?;
    let sym = file
        .symbols()
        .find(|s| s.name() == Ok(name))
        .ok_or_else(|| CcError::BadOutput(format!("no symbol `{name}`")))?;
    let (mut text, mut rodata) = (0u32, 0u32);
    for s in file.sections() {
        if let SectionFlags::Elf { sh_flags, .. } = s.flags() {
            let has = |f: object::elf::SectionFlags| sh_flags.0 & f.0 != 0;
            let alloc = has(object::elf::SHF_ALLOC);
            let exec = has(object::elf::SHF_EXECINSTR);
            let write = has(object::elf::SHF_WRITE);
            if exec {
                text += s.size() as u32;
            } else if alloc && !write {
                rodata += s.size() as u32;
            }
        }
    }
    // Aliases (`__aeabi_lmul` and `__muldi3` are one function) become one entry.
    let mut syms: Vec<(u64, String, u32)> = file
        .symbols()
        .filter(|s| s.kind() == SymbolKind::Text && s.size() > 0)
        .filter_map(|s| {
            Some((
                s.address() & !1,
                s.name().ok()?.to_string(),
                s.size() as u32,
            ))
        })
        .collect();
    syms.sort();
    syms.dedup();
    let mut funcs: Vec<(u64, Function)> = Vec::new();
    for (addr, name, size) in syms {
        match funcs.last_mut() {
            Some((a, f)) if *a == addr => f.name = format!("{}={name}", f.name),
            _ => funcs.push((addr, Function { name, size })),
        }
    }
    let funcs: Vec<Function> = funcs.into_iter().map(|(_, f)| f).collect();
    Ok((sym.size() as u32, (text, rodata, funcs)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_tool_is_named_with_its_package() {
        let e = run(
            &mut Command::new("arm-none-eabi-no-such-tool"),
            "arm-none-eabi-no-such-tool",
        )
        .unwrap_err();
        assert_eq!(
            e,
            CcError::ToolMissing {
                tool: "arm-none-eabi-no-such-tool".into(),
                package: "binutils-arm-none-eabi".into()
            }
        );
        assert!(e
            .to_string()
            .contains("apt-get install binutils-arm-none-eabi"));
        assert_eq!(package_of(Compiler::Gcc.tool()), "gcc-arm-none-eabi");
        assert_eq!(package_of(Compiler::Clang.tool()), "clang");
    }
}
