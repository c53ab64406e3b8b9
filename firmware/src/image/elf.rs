//! The image as a linked ELF executable (`ET_EXEC`, ARM, EABI version 5), written with the
//! `object` crate's ELF writer.
//!
//! One `PT_LOAD` segment and one section per piece of the image. [`FirmwareImage::elf`],
//! the RAM image, has them at their run addresses (virtual = physical): `.entry` (the stub
//! at 0x20000000 the boot ROM enters, [`super::boot`]), per core `.coreN.text` (vector
//! table, program copies, glue: read and execute) and `.coreN.data` (control block, key
//! records, states: read and write); its entry point is the stub.
//! [`FirmwareImage::flash_elf`], the flash image (`super::flash_image`), adds `.boot2` and
//! `.flash_entry` (the flash vector table, reset handler and copy table) at 0x10000000 and
//! 0x10000100, and loads the same SRAM sections from flash: their virtual address is where
//! they run, their physical (load) address where their bytes are in flash, as a
//! `copy_to_ram` binary's `.data` — a flash programmer (or `tactus emu run`) writes the
//! physical bytes, a debugger sees the code where it runs. Its entry point is the flash
//! reset handler. Symbols name what a debugger or the key map needs: the stub
//! (`_entry_point`), per core its vector table, reset handler, sample interrupt, control
//! block and each program copy's `init`/`update` (functions with the Thumb bit, ARM IHI
//! 0044 §5.5.3), per key its record (`keyN_record`, N its window slot), in flash boot2
//! (`_stage2_boot`) and the flash reset handler (`_flash_reset`); the mapping symbols
//! `$t`/`$d` (IHI 0044 §5.5.5) mark the vector tables, literal pools, boot2's padding and
//! CRC, the copy table and the data as data for disassemblers.

use super::boot2::FLASH_VECTORS;
use super::flash_image::FlashImage;
use super::{boot, FirmwareImage, ImageError, VECTORS};
use object::elf;
use object::write::elf::{FileHeader, ProgramHeader, SectionHeader, Sym, Writer};
use object::Endianness;
use tactus_rp2040::memory::FLASH_BASE;

/// `EF_ARM_EABI_VER5` (IHI 0044 §5.2).
const EF_ARM_EABI_VER5: u32 = 0x0500_0000;

/// One symbol before writing.
struct Symbol {
    name: String,
    value: u32,
    size: u32,
    kind: elf::SymbolType,
    local: bool,
}

/// One section and its `PT_LOAD` segment.
struct Piece<'a> {
    name: String,
    /// Run address.
    vaddr: u32,
    /// Load address.
    paddr: u32,
    data: &'a [u8],
    code: bool,
}

/// The RAM image's sections, in segment order: the stub, per core its code and data, per
/// core its I/O block (a converter board), then the re-entry's code and copies
/// (`super::reboot`).
fn ram_pieces(image: &FirmwareImage) -> Vec<Piece<'_>> {
    let cores = image.cores.len();
    let io = if image.io.is_some() { cores } else { 0 };
    image
        .segments
        .iter()
        .enumerate()
        .map(|(i, (addr, data))| {
            let (name, code) = match i {
                0 => (".entry".to_string(), true),
                i if i <= 2 * cores && i % 2 == 1 => (format!(".core{}.text", (i - 1) / 2), true),
                i if i <= 2 * cores => (format!(".core{}.data", (i - 1) / 2), false),
                i if i <= 2 * cores + io => (format!(".core{}.io", i - 1 - 2 * cores), false),
                i if i == 2 * cores + io + 1 => (".reboot".to_string(), true),
                _ => (".reboot.copies".to_string(), false),
            };
            Piece {
                name,
                vaddr: *addr,
                paddr: *addr,
                data,
                code,
            }
        })
        .collect()
}

fn mapping(name: &str, value: u32) -> Symbol {
    Symbol {
        name: name.to_string(),
        value,
        size: 0,
        kind: elf::STT_NOTYPE,
        local: true,
    }
}

fn function(name: String, value: u32, size: u32) -> Symbol {
    Symbol {
        name,
        value: value | 1,
        size,
        kind: elf::STT_FUNC,
        local: false,
    }
}

/// Writes `pieces` with `symbols` (locals first) and entry point `entry`.
fn write_elf(pieces: &[Piece], symbols: &[Symbol], entry: u32) -> Result<Vec<u8>, ImageError> {
    let section_of = |addr: u32| {
        pieces
            .iter()
            .position(|p| addr >= p.vaddr && addr < p.vaddr + p.data.len() as u32)
    };
    let fail = |e: object::write::Error| ImageError::Assemble(format!("writing the ELF: {e}"));
    let mut buf = Vec::new();
    let mut w = Writer::new(Endianness::Little, false, &mut buf);
    w.reserve_file_header();
    w.reserve_program_headers(pieces.len() as u32);
    let offsets: Vec<u64> = pieces
        .iter()
        .map(|p| w.reserve(p.data.len() as u64, 4))
        .collect();
    w.reserve_null_section_index();
    let mut sections = Vec::new();
    for p in pieces {
        let name = w.add_section_name(p.name.as_bytes());
        sections.push((name, w.reserve_section_index()));
    }
    w.reserve_null_symbol_index();
    let mut syms = Vec::new();
    for s in symbols {
        let sec = section_of(s.value & !1).map(|i| sections[i].1);
        let name = w.add_string(s.name.as_bytes());
        w.reserve_symbol_index(sec);
        syms.push((name, sec));
    }
    w.reserve_symtab_section_index();
    w.reserve_symtab();
    w.reserve_strtab_section_index();
    w.reserve_strtab().map_err(fail)?;
    w.reserve_shstrtab_section_index();
    w.reserve_shstrtab().map_err(fail)?;
    w.reserve_section_headers();

    w.write_file_header(&FileHeader {
        os_abi: elf::ELFOSABI_NONE,
        abi_version: 0,
        e_type: elf::ET_EXEC,
        e_machine: elf::EM_ARM,
        e_entry: u64::from(entry),
        e_flags: elf::FileFlags(EF_ARM_EABI_VER5),
    })
    .map_err(fail)?;
    w.write_align_program_headers();
    for (p, &offset) in pieces.iter().zip(&offsets) {
        w.write_program_header(&ProgramHeader {
            p_type: elf::PT_LOAD,
            p_flags: if p.code {
                elf::ProgramFlags(elf::PF_R.0 | elf::PF_X.0)
            } else {
                elf::ProgramFlags(elf::PF_R.0 | elf::PF_W.0)
            },
            p_offset: offset,
            p_vaddr: u64::from(p.vaddr),
            p_paddr: u64::from(p.paddr),
            p_filesz: p.data.len() as u64,
            p_memsz: p.data.len() as u64,
            p_align: 4,
        });
    }
    for p in pieces {
        w.write_align(4);
        w.write(p.data);
    }
    w.write_null_symbol();
    for (s, (name, sec)) in symbols.iter().zip(&syms) {
        let bind = if s.local {
            elf::STB_LOCAL
        } else {
            elf::STB_GLOBAL
        };
        w.write_symbol(&Sym {
            section: sec.map(|s| s.0),
            st_name: w.string_offset(Some(*name)),
            st_info: elf::SymbolInfo::new(bind, s.kind),
            st_other: elf::SymbolOther(0),
            st_shndx: elf::SymbolSection(0),
            st_value: u64::from(s.value),
            st_size: u64::from(s.size),
        });
    }
    w.write_strtab();
    w.write_shstrtab();
    w.write_null_section_header();
    for ((p, (name, _)), &offset) in pieces.iter().zip(&sections).zip(&offsets) {
        let flags = if p.code {
            elf::SHF_ALLOC.0 | elf::SHF_EXECINSTR.0
        } else {
            elf::SHF_ALLOC.0 | elf::SHF_WRITE.0
        };
        w.write_section_header(&SectionHeader {
            sh_name: w.section_name_offset(Some(*name)),
            sh_type: elf::SHT_PROGBITS,
            sh_flags: elf::SectionFlags(flags),
            sh_addr: u64::from(p.vaddr),
            sh_offset: offset,
            sh_size: p.data.len() as u64,
            sh_link: 0,
            sh_info: 0,
            sh_addralign: 4,
            sh_entsize: 0,
        });
    }
    let locals = symbols.iter().filter(|s| s.local).count() as u32;
    w.write_symtab_section_header(locals + 1);
    w.write_strtab_section_header();
    w.write_shstrtab_section_header();
    Ok(buf)
}

impl FirmwareImage {
    /// The RAM image as an ELF executable (see the module documentation).
    ///
    /// Errors: [`ImageError::Assemble`] when the writer fails (it should not).
    pub fn elf(&self) -> Result<Vec<u8>, ImageError> {
        write_elf(&ram_pieces(self), &self.elf_symbols(&[]), boot::ENTRY | 1)
    }

    /// The flash image `flash` ([`FirmwareImage::flash_image`] of this image) as an ELF
    /// executable (see the module documentation).
    ///
    /// Errors: [`ImageError::Assemble`] when the writer fails (it should not) or `flash`
    /// is not this image's.
    pub fn flash_elf(&self, flash: &FlashImage) -> Result<Vec<u8>, ImageError> {
        if flash.pieces.len() != self.segments.len() {
            return Err(ImageError::Assemble(
                "the flash image is not this image's".into(),
            ));
        }
        let at = |addr: u32| (addr - FLASH_BASE) as usize;
        let entry_end = flash.table.1;
        let mut pieces = vec![
            Piece {
                name: ".boot2".into(),
                vaddr: FLASH_BASE,
                paddr: FLASH_BASE,
                data: &flash.bytes[..at(FLASH_VECTORS)],
                code: true,
            },
            Piece {
                name: ".flash_entry".into(),
                vaddr: FLASH_VECTORS,
                paddr: FLASH_VECTORS,
                data: &flash.bytes[at(FLASH_VECTORS)..at(entry_end)],
                code: true,
            },
        ];
        for (p, fp) in ram_pieces(self).into_iter().zip(&flash.pieces) {
            pieces.push(Piece {
                paddr: fp.flash,
                ..p
            });
        }
        let mut extra = vec![mapping("$t", FLASH_BASE), mapping("$t", flash.reset)];
        for &(off, _) in &flash.boot2_data {
            extra.push(mapping("$d", FLASH_BASE + off as u32));
        }
        extra.push(mapping("$d", FLASH_BASE + flash.boot2_code as u32));
        for &(addr, _) in &flash.data {
            extra.push(mapping("$d", addr));
        }
        extra.push(function(
            "_stage2_boot".into(),
            FLASH_BASE,
            flash.boot2_code as u32,
        ));
        extra.push(function("_flash_reset".into(), flash.reset, 0));
        write_elf(&pieces, &self.elf_symbols(&extra), flash.reset | 1)
    }

    /// The symbols of [`FirmwareImage::elf`] and `extra`, locals (the mapping symbols)
    /// first.
    fn elf_symbols(&self, extra: &[Symbol]) -> Vec<Symbol> {
        let mut locals = Vec::new();
        let mut globals = Vec::new();
        for s in extra {
            let copy = Symbol {
                name: s.name.clone(),
                ..*s
            };
            if s.local {
                locals.push(copy);
            } else {
                globals.push(copy);
            }
        }
        let map = mapping;
        let func = function;
        let object = |name: String, value: u32, size: u32| Symbol {
            name,
            value,
            size,
            kind: elf::STT_OBJECT,
            local: false,
        };
        locals.push(map("$t", boot::ENTRY));
        // The stub's literal pool after its code.
        locals.push(map("$d", boot::ENTRY + boot::ENTRY_STUB_CODE));
        globals.push(func("_entry_point".into(), boot::ENTRY, 0));
        globals.push(func("_entry_from_flash".into(), boot::ENTRY_FROM_FLASH, 0));
        if let Ok(r) = &self.reentry {
            // The re-entry's code, then its pool, table and copies (`super::reboot`).
            locals.push(map("$t", super::reboot::REENTRY));
            locals.push(map("$d", r.pool));
            globals.push(func("_reentry".into(), super::reboot::REENTRY, 0));
        }
        for (c, place) in self.cores.iter().enumerate() {
            locals.push(map("$d", place.vtor));
            locals.push(map("$t", place.vtor + VECTORS));
            globals.push(object(format!("core{c}_vectors"), place.vtor, VECTORS));
            globals.push(func(format!("core{c}_reset"), place.reset, 0));
            globals.push(func(format!("core{c}_sample_isr"), place.isr, 0));
            globals.push(object(
                format!("core{c}_control"),
                place.ctrl,
                super::glue::ctrl::SIZE,
            ));
            locals.push(map("$d", place.ctrl));
            // Each program copy this core's keys call, once.
            let mut seen = Vec::new();
            for &k in &place.keys {
                let key = &self.keys[k];
                let p = &self.programs[key.spec.program];
                let Some((off, _)) = p.thumb.symbol(&p.thumb.update_name()) else {
                    continue;
                };
                let text = key.update - off as u32;
                if seen.contains(&text) {
                    continue;
                }
                seen.push(text);
                for (name, off, size) in &p.thumb.code.symbols {
                    globals.push(func(
                        format!("core{c}_{name}"),
                        text + *off as u32,
                        *size as u32,
                    ));
                }
                for &(off, len) in &p.thumb.code.data {
                    locals.push(map("$d", text + off as u32));
                    if off + len < p.thumb.code.text.len() {
                        locals.push(map("$t", text + (off + len) as u32));
                    }
                }
                let end = text + p.thumb.code.text.len() as u32;
                locals.push(map("$t", end.next_multiple_of(4)));
            }
            for &k in &place.keys {
                let key = &self.keys[k];
                let size = 4 * (key.sensors + key.out_len + key.drives.len() + 1) as u32;
                globals.push(object(
                    format!("key{}_record", key.spec.slot),
                    key.record,
                    size,
                ));
            }
        }
        locals.extend(globals);
        locals
    }
}
