//! Loading ELF executables (`object` crate) into an [`Image`]: what to copy where, where to
//! start, and the symbol table.
//!
//! The loader works from program headers, copying each `PT_LOAD` segment to its *physical*
//! (load) address, as a flash programmer would: firmware whose `.data` is linked to run in
//! SRAM but stored in flash copies it itself at startup. Symbols keep their names and
//! addresses with the Thumb bit cleared, so the board can account cycles per function.
//! Everything is checked before anything is copied: a truncated file, a non-ARM or
//! big-endian or 64-bit ELF, or a relocatable object gives an [`ElfError`], never a panic.
//! A segment's size comes from the file, so it is checked against the RP2040's memory map
//! ([`memory_region`]: ROM, flash, SRAM and its non-striped alias) *before* its zero-filled
//! tail is allocated: a `p_memsz` of 0xFFFFFFFF is an [`ElfError::Unmapped`], not a 4 GB
//! allocation.

use object::elf;
use object::read::elf::{FileHeader, ProgramHeader};
use object::{Object, ObjectSection, ObjectSymbol, SymbolKind};
use std::fmt;
use tactus_rp2040::memory::{
    FLASH_BASE, FLASH_SIZE, ROM_BASE, ROM_SIZE, SRAM_ALIAS_BASE, SRAM_BASE, SRAM_SIZE,
};

/// The emulated memories a segment may be loaded into: (base, size in bytes) of ROM,
/// flash, SRAM and the non-striped alias of SRAM0–3 (`bus.rs` defines each).
const REGIONS: [(u32, u32); 4] = [
    (ROM_BASE, ROM_SIZE),
    (FLASH_BASE, FLASH_SIZE),
    (SRAM_BASE, SRAM_SIZE),
    (SRAM_ALIAS_BASE, 0x4_0000),
];

/// The bytes of every region together: the most all segments of one file may fill.
const TOTAL_MEMORY: u64 = ROM_SIZE as u64 + FLASH_SIZE as u64 + SRAM_SIZE as u64 + 0x4_0000;

/// The memory region (base, size) that holds all of `size` bytes from `addr`, if one does;
/// an empty range needs only its address inside a region.
pub fn memory_region(addr: u32, size: u32) -> Option<(u32, u32)> {
    REGIONS.iter().copied().find(|&(base, len)| {
        let off = addr.wrapping_sub(base);
        off < len && u64::from(off) + u64::from(size) <= u64::from(len)
    })
}

/// A symbol from the ELF symbol table.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Symbol {
    /// Symbol name.
    pub name: String,
    /// Address in bytes, Thumb bit cleared.
    pub addr: u32,
    /// Size in bytes (0 if unknown).
    pub size: u32,
    /// True for functions (STT_FUNC).
    pub is_function: bool,
}

/// A loadable segment.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Segment {
    /// Physical (load) address.
    pub addr: u32,
    /// Virtual address: where the running program finds these bytes. The load address for
    /// an image that runs where it is loaded; for one that copies itself from flash to SRAM
    /// (pico-sdk's `copy_to_ram`, `tactus build`'s flash images) the SRAM address.
    pub run_addr: u32,
    /// Bytes to copy; the segment's `p_memsz - p_filesz` tail is zero-filled.
    pub data: Vec<u8>,
}

/// A parsed executable, ready to load.
#[derive(Clone, Debug, Default)]
pub struct Image {
    /// Entry point (Thumb bit included, as in the ELF header).
    pub entry: u32,
    /// Segments to copy.
    pub segments: Vec<Segment>,
    /// Symbols (functions and objects with a name).
    pub symbols: Vec<Symbol>,
    /// Address of a vector table, if a section named `.vectors`, `.vector_table` or
    /// `.isr_vector` exists.
    pub vector_table: Option<u32>,
    /// Whether a section named `.boot2` exists (pico-sdk's name for the second-stage boot
    /// loader at the start of flash): the image boots from flash through the boot ROM.
    pub boot2: bool,
}

impl Image {
    /// The symbol named `name`.
    pub fn symbol(&self, name: &str) -> Option<&Symbol> {
        self.symbols.iter().find(|s| s.name == name)
    }

    /// The function symbol containing `addr`, if any.
    pub fn function_at(&self, addr: u32) -> Option<&Symbol> {
        self.symbols
            .iter()
            .filter(|s| s.is_function)
            .find(|s| addr >= s.addr && addr < s.addr.saturating_add(s.size.max(1)))
    }
}

/// Why an ELF file could not be loaded.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ElfError {
    /// Not a parseable ELF file (truncated, corrupt, or another format).
    Malformed(String),
    /// An ELF for another machine, class or byte order.
    NotArm(String),
    /// A relocatable object (`.o`): link it into an executable first.
    Relocatable,
    /// Not an executable (shared object, core dump, ...).
    NotExecutable,
    /// A segment lies outside emulated ROM, flash and SRAM.
    Unmapped {
        /// Segment address.
        addr: u32,
        /// Segment size in bytes.
        size: u32,
    },
}

impl fmt::Display for ElfError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ElfError::Malformed(e) => write!(f, "not a valid ELF file: {e}"),
            ElfError::NotArm(what) => write!(f, "not a 32-bit little-endian ARM ELF ({what})"),
            ElfError::Relocatable => {
                write!(
                    f,
                    "relocatable object file: link it into an executable first"
                )
            }
            ElfError::NotExecutable => write!(f, "ELF file is not an executable"),
            ElfError::Unmapped { addr, size } => write!(
                f,
                "segment at {addr:#010x} ({size} bytes) is outside the RP2040's ROM, flash and SRAM"
            ),
        }
    }
}

impl std::error::Error for ElfError {}

/// Parses an ELF executable for ARM.
pub fn parse(bytes: &[u8]) -> Result<Image, ElfError> {
    if bytes.len() < 5 || &bytes[..4] != b"\x7fELF" {
        return Err(ElfError::Malformed("missing ELF magic".into()));
    }
    if bytes[4] != 1 {
        // EI_CLASS: 1 = ELFCLASS32
        return Err(ElfError::NotArm("64-bit ELF".into()));
    }
    let header = elf::FileHeader32::<object::Endianness>::parse(bytes)
        .map_err(|e| ElfError::Malformed(e.to_string()))?;
    let endian = header
        .endian()
        .map_err(|e| ElfError::Malformed(e.to_string()))?;
    if !header.is_little_endian() {
        return Err(ElfError::NotArm("big-endian".into()));
    }
    let machine = header.e_machine(endian);
    if machine != elf::EM_ARM {
        return Err(ElfError::NotArm(format!("e_machine {}", machine.0)));
    }
    let kind = header.e_type(endian);
    if kind == elf::ET_REL {
        return Err(ElfError::Relocatable);
    }
    if kind != elf::ET_EXEC {
        return Err(ElfError::NotExecutable);
    }
    let mut image = Image {
        entry: header.e_entry(endian),
        ..Image::default()
    };
    let phdrs = header
        .program_headers(endian, bytes)
        .map_err(|e| ElfError::Malformed(e.to_string()))?;
    let mut total = 0u64;
    for ph in phdrs {
        if ph.p_type(endian) != elf::PT_LOAD || ph.p_memsz(endian) == 0 {
            continue;
        }
        let data = ph
            .data(endian, bytes)
            .map_err(|()| ElfError::Malformed("segment data beyond the end of the file".into()))?;
        let memsz = ph.p_memsz(endian);
        if (memsz as usize) < data.len() {
            return Err(ElfError::Malformed("segment p_memsz < p_filesz".into()));
        }
        let addr = ph.p_paddr(endian);
        if memory_region(addr, memsz).is_none() {
            return Err(ElfError::Unmapped { addr, size: memsz });
        }
        // Each segment fits a region, but 65,535 program headers could each claim one.
        total = total.saturating_add(u64::from(memsz));
        if total > TOTAL_MEMORY {
            return Err(ElfError::Malformed(format!(
                "the segments add up to more than the {TOTAL_MEMORY} bytes of emulated memory"
            )));
        }
        let mut data = data.to_vec();
        data.resize(memsz as usize, 0);
        let run_addr = ph.p_vaddr(endian);
        image.segments.push(Segment {
            addr,
            run_addr,
            data,
        });
    }
    let file = object::File::parse(bytes).map_err(|e| ElfError::Malformed(e.to_string()))?;
    for sym in file.symbols() {
        let Ok(name) = sym.name() else { continue };
        if name.is_empty() || name.starts_with('$') || sym.is_undefined() {
            continue;
        }
        let is_function = sym.kind() == SymbolKind::Text;
        let addr = sym.address() as u32;
        image.symbols.push(Symbol {
            name: name.to_string(),
            addr: if is_function { addr & !1 } else { addr },
            size: sym.size() as u32,
            is_function,
        });
    }
    for section in file.sections() {
        if matches!(
            section.name(),
            Ok(".vectors" | ".vector_table" | ".isr_vector")
        ) {
            image.vector_table = Some(section.address() as u32);
        }
        if section.name() == Ok(".boot2") {
            image.boot2 = true;
        }
    }
    Ok(image)
}
