//! The ARMv6-M (Cortex-M0+) register file as GDB sees it, for `gdbstub`.
//!
//! `gdbstub_arch` describes ARMv4T only (its `cpsr`, its eight FPA registers), so this is
//! the M-profile description GDB itself ships (`gdb/features/arm/arm-m-profile.xml`: r0–r12,
//! sp, lr, pc, xpsr) with the system registers of ARMv6-M after it (msp and psp as in
//! `arm-m-system.xml`; primask and control in a feature of our own). The `g` packet holds
//! them in that order, four little-endian bytes each.

use crate::core::Core;
use gdbstub::arch::{Arch, RegId, Registers};

/// The target description sent to GDB (`qXfer:features:read`).
pub const TARGET_XML: &str = r#"<?xml version="1.0"?>
<!DOCTYPE target SYSTEM "gdb-target.dtd">
<target version="1.0">
  <architecture>arm</architecture>
  <feature name="org.gnu.gdb.arm.m-profile">
    <reg name="r0" bitsize="32" regnum="0"/>
    <reg name="r1" bitsize="32"/>
    <reg name="r2" bitsize="32"/>
    <reg name="r3" bitsize="32"/>
    <reg name="r4" bitsize="32"/>
    <reg name="r5" bitsize="32"/>
    <reg name="r6" bitsize="32"/>
    <reg name="r7" bitsize="32"/>
    <reg name="r8" bitsize="32"/>
    <reg name="r9" bitsize="32"/>
    <reg name="r10" bitsize="32"/>
    <reg name="r11" bitsize="32"/>
    <reg name="r12" bitsize="32"/>
    <reg name="sp" bitsize="32" type="data_ptr"/>
    <reg name="lr" bitsize="32"/>
    <reg name="pc" bitsize="32" type="code_ptr"/>
    <reg name="xpsr" bitsize="32"/>
  </feature>
  <feature name="org.gnu.gdb.arm.m-system">
    <reg name="msp" bitsize="32" type="data_ptr"/>
    <reg name="psp" bitsize="32" type="data_ptr"/>
  </feature>
  <feature name="org.tactus.arm.v6m-system">
    <reg name="primask" bitsize="32"/>
    <reg name="control" bitsize="32"/>
  </feature>
</target>"#;

/// The number of registers in [`TARGET_XML`].
pub const REGISTERS: usize = 21;

/// ARMv6-M for `gdbstub`.
pub enum ArmV6m {}

impl Arch for ArmV6m {
    type Usize = u32;
    type Registers = V6mRegs;
    type RegId = V6mRegId;
    type BreakpointKind = usize;

    fn target_description_xml() -> Option<&'static str> {
        Some(TARGET_XML)
    }
}

/// One register by its number in [`TARGET_XML`] (0–15 r0–pc, 16 xpsr, 17 msp, 18 psp,
/// 19 primask, 20 control).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct V6mRegId(pub usize);

impl RegId for V6mRegId {
    fn from_raw_id(id: usize) -> Option<(Self, Option<std::num::NonZeroUsize>)> {
        (id < REGISTERS).then(|| (V6mRegId(id), std::num::NonZeroUsize::new(4)))
    }
}

/// The registers of one core, in [`TARGET_XML`] order.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct V6mRegs {
    /// r0–r15 (r13 the active stack pointer, r15 the address of the next instruction).
    pub r: [u32; 16],
    /// xPSR: APSR flags, EPSR.T, IPSR.
    pub xpsr: u32,
    /// Main stack pointer.
    pub msp: u32,
    /// Process stack pointer.
    pub psp: u32,
    /// PRIMASK (bit 0).
    pub primask: u32,
    /// CONTROL (bit 1 SPSEL, bit 0 nPRIV).
    pub control: u32,
}

impl V6mRegs {
    /// The registers of `core`.
    pub fn of(core: &Core) -> Self {
        V6mRegs {
            r: core.r,
            xpsr: core.xpsr(),
            msp: core.msp(),
            psp: core.psp(),
            primask: core.primask as u32,
            control: core.control,
        }
    }

    /// Writes these registers into `core`: r0–r15, the APSR flags of xpsr (EPSR and IPSR
    /// are the exception state: not writable, as over SWD), the stack pointer not in r13
    /// from msp or psp, PRIMASK. CONTROL is read-only here (writing SPSEL would exchange
    /// the stacks under the program).
    pub fn write_to(&self, core: &mut Core) {
        let pc = self.r[15] & !1;
        core.r = self.r;
        core.r[15] = pc;
        core.set_apsr(self.xpsr);
        let psp_active = core.ipsr == 0 && core.control & 2 != 0;
        core.other_sp = if psp_active { self.msp } else { self.psp };
        core.primask = self.primask & 1 != 0;
    }

    fn words(&self) -> [u32; REGISTERS] {
        let mut w = [0; REGISTERS];
        w[..16].copy_from_slice(&self.r);
        w[16] = self.xpsr;
        w[17] = self.msp;
        w[18] = self.psp;
        w[19] = self.primask;
        w[20] = self.control;
        w
    }

    /// Sets register `id` (a [`V6mRegId`]) to `v`; false for an unknown number.
    pub fn set(&mut self, id: usize, v: u32) -> bool {
        match id {
            0..=15 => self.r[id] = v,
            16 => self.xpsr = v,
            17 => self.msp = v,
            18 => self.psp = v,
            19 => self.primask = v,
            20 => self.control = v,
            _ => return false,
        }
        true
    }

    /// Register `id`, if there is one.
    pub fn get(&self, id: usize) -> Option<u32> {
        self.words().get(id).copied()
    }
}

impl Registers for V6mRegs {
    type ProgramCounter = u32;

    fn pc(&self) -> u32 {
        self.r[15]
    }

    fn gdb_serialize(&self, mut write_byte: impl FnMut(Option<u8>)) {
        for w in self.words() {
            for b in w.to_le_bytes() {
                write_byte(Some(b));
            }
        }
    }

    fn gdb_deserialize(&mut self, bytes: &[u8]) -> Result<(), ()> {
        if bytes.len() != REGISTERS * 4 {
            return Err(());
        }
        for (i, c) in bytes.chunks_exact(4).enumerate() {
            self.set(i, u32::from_le_bytes([c[0], c[1], c[2], c[3]]));
        }
        Ok(())
    }
}
