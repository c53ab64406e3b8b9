//! The ELF relocatable object of a compiled instrument (the `object` crate's writer).
//!
//! One `.text` section (4-byte aligned, the code is position independent) with a global
//! `STT_FUNC` symbol per function (value with the Thumb bit set, as the ARM ELF ABI, ARM
//! IHI 0044, §5.5.3 requires for Thumb functions), the mapping symbols `$t`/`$d` that
//! disassemblers and linkers use to tell code from literal pools (IHI 0044 §5.5.5), and
//! `e_flags` = EABI version 5. There are no relocations: every reference is PC-relative
//! inside the section.

use super::emit::Code;
use super::ThumbError;
use object::write::{Object, StandardSection, Symbol, SymbolSection};
use object::{
    Architecture, BinaryFormat, Endianness, FileFlags, SymbolFlags, SymbolKind, SymbolScope,
};

/// `EF_ARM_EABI_VER5` (IHI 0044 §5.2).
const EF_ARM_EABI_VER5: u32 = 0x0500_0000;

/// Writes `code` as an ELF relocatable object.
pub fn write(code: &Code) -> Result<Vec<u8>, ThumbError> {
    let mut obj = Object::new(BinaryFormat::Elf, Architecture::Arm, Endianness::Little);
    obj.flags = FileFlags::Elf {
        os_abi: object::elf::OsAbi(0),
        abi_version: 0,
        e_flags: object::elf::FileFlags(EF_ARM_EABI_VER5),
    };
    let text = obj.section_id(StandardSection::Text);
    obj.append_section_data(text, &code.text, 4);
    let local = |name: &str, value: u64| Symbol {
        name: name.as_bytes().to_vec(),
        value,
        size: 0,
        kind: SymbolKind::Label,
        scope: SymbolScope::Compilation,
        weak: false,
        section: SymbolSection::Section(text),
        flags: SymbolFlags::None,
    };
    // Mapping symbols: code from 0 and after every pool, data at every pool.
    obj.add_symbol(local("$t", 0));
    for &(off, len) in &code.data {
        obj.add_symbol(local("$d", off as u64));
        if off + len < code.text.len() {
            obj.add_symbol(local("$t", (off + len) as u64));
        }
    }
    for (name, off, size) in &code.symbols {
        obj.add_symbol(Symbol {
            name: name.as_bytes().to_vec(),
            value: *off as u64 | 1,
            size: *size as u64,
            kind: SymbolKind::Text,
            scope: SymbolScope::Dynamic,
            weak: false,
            section: SymbolSection::Section(text),
            flags: SymbolFlags::None,
        });
    }
    obj.write()
        .map_err(|e| ThumbError::Encoding(format!("writing the ELF object: {e}")))
}
