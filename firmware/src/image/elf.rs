//! The image as a linked ELF executable (`ET_EXEC`, ARM, EABI version 5), written with the
//! `object` crate's ELF writer.
//!
//! One `PT_LOAD` segment and one section per piece of the image, at its run address
//! (virtual = physical): `.entry` (the stub at 0x20000000 the boot ROM enters,
//! [`super::boot`]), per core `.coreN.text` (vector table, program copies, glue: read and
//! execute) and `.coreN.data` (control block, key records, states: read and write). The
//! entry point is the stub. Symbols name what a debugger or the key map needs: the stub
//! (`_entry_point`), per core its vector table, reset handler, sample interrupt, control
//! block and each program copy's `init`/`update` (functions with the Thumb bit, ARM IHI
//! 0044 §5.5.3), per key its record (`keyN_record`, N its window slot); the mapping
//! symbols `$t`/`$d` (IHI 0044 §5.5.5) mark the vector tables, the programs' literal pools
//! and the data as data for disassemblers.

use super::{boot, FirmwareImage, ImageError, VECTORS};
use object::elf;
use object::write::elf::{FileHeader, ProgramHeader, SectionHeader, Sym, Writer};
use object::Endianness;

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

impl FirmwareImage {
    /// The image as an ELF executable (see the module documentation).
    ///
    /// Errors: [`ImageError::Assemble`] when the writer fails (it should not).
    pub fn elf(&self) -> Result<Vec<u8>, ImageError> {
        // Section names, in segment order: the stub, then per core its code and data.
        let mut names: Vec<String> = Vec::new();
        for (i, _) in self.segments.iter().enumerate() {
            names.push(match i {
                0 => ".entry".to_string(),
                i if i % 2 == 1 => format!(".core{}.text", (i - 1) / 2),
                i => format!(".core{}.data", (i - 1) / 2),
            });
        }
        let symbols = self.elf_symbols();
        let section_of = |addr: u32| {
            self.segments
                .iter()
                .position(|(b, d)| addr >= *b && addr < b + d.len() as u32)
        };

        let fail = |e: object::write::Error| ImageError::Assemble(format!("writing the ELF: {e}"));
        let mut buf = Vec::new();
        let mut w = Writer::new(Endianness::Little, false, &mut buf);
        w.reserve_file_header();
        w.reserve_program_headers(self.segments.len() as u32);
        let offsets: Vec<u64> = self
            .segments
            .iter()
            .map(|(_, d)| w.reserve(d.len() as u64, 4))
            .collect();
        w.reserve_null_section_index();
        let mut sections = Vec::new();
        for n in &names {
            let name = w.add_section_name(n.as_bytes());
            sections.push((name, w.reserve_section_index()));
        }
        w.reserve_null_symbol_index();
        let mut syms = Vec::new();
        for s in &symbols {
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
            e_entry: u64::from(boot::ENTRY | 1),
            e_flags: elf::FileFlags(EF_ARM_EABI_VER5),
        })
        .map_err(fail)?;
        w.write_align_program_headers();
        for (i, (addr, data)) in self.segments.iter().enumerate() {
            let code = i == 0 || i % 2 == 1;
            w.write_program_header(&ProgramHeader {
                p_type: elf::PT_LOAD,
                p_flags: if code {
                    elf::ProgramFlags(elf::PF_R.0 | elf::PF_X.0)
                } else {
                    elf::ProgramFlags(elf::PF_R.0 | elf::PF_W.0)
                },
                p_offset: offsets[i],
                p_vaddr: u64::from(*addr),
                p_paddr: u64::from(*addr),
                p_filesz: data.len() as u64,
                p_memsz: data.len() as u64,
                p_align: 4,
            });
        }
        for (_, data) in &self.segments {
            w.write_align(4);
            w.write(data);
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
        for (i, ((addr, data), (name, _))) in self.segments.iter().zip(&sections).enumerate() {
            let code = i == 0 || i % 2 == 1;
            let flags = if code {
                elf::SHF_ALLOC.0 | elf::SHF_EXECINSTR.0
            } else {
                elf::SHF_ALLOC.0 | elf::SHF_WRITE.0
            };
            w.write_section_header(&SectionHeader {
                sh_name: w.section_name_offset(Some(*name)),
                sh_type: elf::SHT_PROGBITS,
                sh_flags: elf::SectionFlags(flags),
                sh_addr: u64::from(*addr),
                sh_offset: offsets[i],
                sh_size: data.len() as u64,
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

    /// The symbols of [`FirmwareImage::elf`], locals (the mapping symbols) first.
    fn elf_symbols(&self) -> Vec<Symbol> {
        let mut locals = Vec::new();
        let mut globals = Vec::new();
        let map = |name: &str, value: u32| Symbol {
            name: name.to_string(),
            value,
            size: 0,
            kind: elf::STT_NOTYPE,
            local: true,
        };
        let func = |name: String, value: u32, size: u32| Symbol {
            name,
            value: value | 1,
            size,
            kind: elf::STT_FUNC,
            local: false,
        };
        let object = |name: String, value: u32, size: u32| Symbol {
            name,
            value,
            size,
            kind: elf::STT_OBJECT,
            local: false,
        };
        locals.push(map("$t", boot::ENTRY));
        if let Some((_, stub)) = self.segments.first() {
            // The stub's literal pool: its last two words.
            let pool = boot::ENTRY + (stub.len() as u32).saturating_sub(8);
            locals.push(map("$d", pool));
        }
        globals.push(func("_entry_point".into(), boot::ENTRY, 0));
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
