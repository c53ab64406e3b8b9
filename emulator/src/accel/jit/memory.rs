//! Loads and stores as cranelift IR: the address paths (striped SRAM, SRAM4/5, the
//! non-striped aliases, flash), the inline bank arbiter, the code-page check after a
//! store, and the multiple transfers (PUSH, POP, STM, LDM) — `Core::mem_fast`,
//! `push_fast`, `pop_fast` in `exec.rs`.
//!
//! A single access tries the views in the order programs use them, each in one unsigned
//! comparison that also checks the alignment (the offset into the view rotated right by
//! log2(size) is below the view's size >> log2(size) exactly when it is in the view and
//! aligned): the striped view, then the non-striped alias (each core's data in the
//! firmware images) — the other way round in a region fetched through the alias; only then does an unaligned access leave for the general path and an
//! aligned one try SRAM4/5 and flash. Offsets and bank offsets are 64-bit from the view on,
//! so the common path widens nothing twice.

use super::abi::{io_reg, io_sram, ppb_load, ppb_store, Ctx, Exit, SYST_RVR};
use super::scan::RegionInstr;
use super::translate::Translator;
use crate::nvic::PPB_BASE;
use cranelift_codegen::ir::condcodes::IntCC;
use cranelift_codegen::ir::{types, AbiParam, BlockArg, InstBuilder, Signature, Value};
use cranelift_frontend::FunctionBuilder;
use std::mem::offset_of;
use tactus_isa::decode::MemOp;
use tactus_rp2040::memory::{FLASH_BASE, FLASH_SIZE, SRAM_ALIAS_BASE, SRAM_BASE, SRAM_SIZE};

impl Translator<'_> {
    /// POP (`rn` 13) or LDM: the words, the base write-back (LDM: unless the base is
    /// loaded), the registers, and for POP {…, pc} the branch; false when it branched.
    pub(super) fn load_multiple(&mut self, ins: &RegionInstr, rn: u8, list: u16) -> bool {
        let count = list.count_ones();
        let start = self.reg(rn, ins.pc);
        let pops_pc = rn == 13 && list & 0x8000 != 0;
        let (loaded, wait, _) = self.multiple(ins, start, count, None, pops_pc);
        if rn == 13 || list & (1 << rn) == 0 {
            let end = self.b.ins().iadd_imm_s(start, 4 * count as i64);
            self.set(rn, end);
        }
        let regs: Vec<u8> = (0..16u8).filter(|r| list & (1 << r) != 0).collect();
        let mut target = None;
        for (&r, &v) in regs.iter().zip(&loaded) {
            if r == 15 {
                target = Some(self.b.ins().band_imm_u(v, !1u32 as i64));
            } else {
                self.set(r, v);
            }
        }
        self.retire(ins.cost.0, wait);
        match target {
            Some(t) => {
                self.leave(t, Exit::Out);
                false
            }
            None => true,
        }
    }

    /// The claim-table offset (`bank · 16`, i64) of SRAM offset `off` (below
    /// [`SRAM_SIZE`]; `bus::sram_bank`): bits 3:2 in the striped banks, then SRAM4, SRAM5.
    /// `striped` is `off < 0x40000` when the caller has it.
    fn bank_offset(&mut self, off: Value, striped: Option<Value>) -> Value {
        let striped = striped.unwrap_or_else(|| {
            self.b
                .ins()
                .icmp_imm_u(IntCC::UnsignedLessThan, off, 0x4_0000)
        });
        let s = self.striped_bank_offset(off);
        let h = self.scratch_bank_offset(off);
        let r = self.b.ins().select(striped, s, h);
        self.b.ins().uextend(types::I64, r)
    }

    /// `bank · 16` (of `off`'s type) of a striped SRAM offset: `((off >> 2) & 3) << 4`.
    fn striped_bank_offset(&mut self, off: Value) -> Value {
        let x = self.b.ins().ishl_imm_u(off, 2);
        self.b.ins().band_imm_u(x, 0x30)
    }

    /// `bank · 16` (of `off`'s type) of an SRAM4/5 offset: `(4 + ((off >> 12) & 1)) << 4`.
    fn scratch_bank_offset(&mut self, off: Value) -> Value {
        let x = self.b.ins().ushr_imm_u(off, 8);
        let x = self.b.ins().band_imm_u(x, 0x10);
        self.b.ins().iadd_imm_s(x, 0x40)
    }

    /// Confined code only (see the parent module, "Confinement"): leaves before the
    /// instruction at `ins` unless every SRAM access in `at` (offset, bank) is in an allowed
    /// bank; then, for a store with a journal, journals the old words it will overwrite (the journal's room
    /// was checked at the region's entry or last back edge, [`Translator::journal_room`]).
    /// Nothing when the code is not confined.
    /// `aligned`: the offsets are word-aligned already (word accesses).
    fn confine(&mut self, ins: &RegionInstr, at: &[(Value, Value)], store: bool, aligned: bool) {
        let boffs: Vec<Value> = at.iter().map(|&(_, boff)| boff).collect();
        self.confine_banks(ins, &boffs);
        self.journal(at, store, aligned);
    }

    /// The bank (i32) of bank offset `boff` (`bank · 16`, i64: [`Translator::bank_offset`]),
    /// and `mask` (i32, bit *b* for bank *b*) shifted right by it: bit 0 is the bank's.
    fn bank_bit(&mut self, mask: Value, boff: Value) -> (Value, Value) {
        let bank = self.b.ins().ushr_imm_u(boff, 4);
        let bank = self.b.ins().ireduce(types::I32, bank);
        (bank, self.b.ins().ushr(mask, bank))
    }

    /// Confined code only: leaves before the instruction at `ins` unless every bank offset
    /// in `boffs` is of an allowed bank.
    fn confine_banks(&mut self, ins: &RegionInstr, boffs: &[Value]) {
        let Some(c) = self.confined else {
            return;
        };
        let mask = self.allowed(c);
        let mut allowed = None;
        for &boff in boffs {
            let (_, bit) = self.bank_bit(mask, boff);
            allowed = Some(match allowed {
                None => bit,
                Some(a) => self.b.ins().band(a, bit),
            });
        }
        if let Some(a) = allowed {
            let ok = self.b.ins().band_imm_u(a, 1);
            self.general_unless(ok, ins.pc);
        }
    }

    /// Confined code only: for a store with a journal, journals the old words at the
    /// offsets of `at` (see [`Translator::confine`]).
    fn journal(&mut self, at: &[(Value, Value)], store: bool, aligned: bool) {
        let Some(c) = self.confined.filter(|c| c.journaled) else {
            return;
        };
        if store {
            let write = self.b.create_block();
            let done = self.b.create_block();
            self.b.ins().jump(write, &[]);
            self.b.switch_to_block(write);
            let len = self.b.use_var(c.len);
            let slot = self.b.ins().ishl_imm_u(len, 3);
            let journal = self.ctx_ptr(offset_of!(Ctx, journal));
            let slot = self.b.ins().iadd(journal, slot);
            for (k, &(off, _)) in at.iter().enumerate() {
                let word = if aligned {
                    off
                } else {
                    self.b.ins().band_imm_u(off, !3u32 as i64)
                };
                let word = if self.b.func.dfg.value_type(word) == types::I64 {
                    word
                } else {
                    self.b.ins().uextend(types::I64, word)
                };
                let p = self.b.ins().iadd(self.sram, word);
                let old = self.b.ins().uload32(self.mf, p, 0);
                let key = self.b.ins().ishl_imm_u(word, 32);
                let entry = self.b.ins().bor(key, old);
                self.b.ins().store(self.mf, entry, slot, 8 * k as i32);
            }
            let len = self.b.ins().iadd_imm_s(len, at.len() as i64);
            self.b.def_var(c.len, len);
            self.b.ins().jump(done, &[]);
            self.b.switch_to_block(done);
        }
    }

    /// The SRAM arbiter for an access to the bank at claim-table offset `boff` (from
    /// [`Translator::bank_offset`]) at data cycle `at`: claims the bank and returns the
    /// wait (0 or 1, i64; `System::arbitrate_fast`) — `None` in [`Flavour::Solo`](super::Flavour::Solo) code,
    /// where the other core's claims are all older than `at` and only the claim is stored.
    pub(super) fn arbitrate(&mut self, boff: Value, at: Value) -> Option<Value> {
        let self_at = self.b.ins().iadd(self.claims_self, boff);
        let Some(claims_other) = self.claims_other else {
            self.b.ins().store(self.mf, at, self_at, 0);
            return None;
        };
        let other_at = self.b.ins().iadd(claims_other, boff);
        let other = self.b.ins().load(types::I64, self.mf, other_at, 0);
        let hit = self.b.ins().icmp(IntCC::Equal, other, at);
        let wait = self.b.ins().uextend(types::I64, hit);
        let claim = self.b.ins().iadd(at, wait);
        self.b.ins().store(self.mf, claim, self_at, 0);
        // Arbitrating code keeps its stalls (`Translator::stalls`, set where the other
        // core's claims are).
        if let Some(stalls) = self.stalls {
            let s = self.b.use_var(stalls);
            let s = self.b.ins().iadd(s, wait);
            self.b.def_var(stalls, s);
        }
        Some(wait)
    }

    /// A single load or store (`Core::mem_fast`): SRAM (striped, SRAM4/5 or the
    /// non-striped aliases) or a flash load; anything else leaves before it.
    /// Branches on whether `rel`, an offset into a view of `len` bytes, is inside it and a
    /// multiple of `1 << shift` (the access size): rotated right by `shift`, the alignment
    /// bits land on top, so one unsigned comparison with `len >> shift` checks both. Leaves
    /// the builder in the taken block and returns the block for the other case.
    fn in_view(&mut self, rel: Value, shift: i64, len: i64) -> cranelift_codegen::ir::Block {
        let key = if shift == 0 {
            rel
        } else {
            self.b.ins().rotr_imm_u(rel, shift)
        };
        let ok = self
            .b
            .ins()
            .icmp_imm_u(IntCC::UnsignedLessThan, key, len >> shift);
        let hit = self.b.create_block();
        let next = self.b.create_block();
        self.b.ins().brif(ok, hit, &[], next, &[]);
        self.b.switch_to_block(hit);
        next
    }

    pub(super) fn mem(&mut self, ins: &RegionInstr, op: MemOp, rt: u8, addr: Value) -> bool {
        let pc = ins.pc;
        let size = op.size();
        let solo = self.claims_other.is_none();
        self.flush();
        // SRAM: (physical offset, claim-table offset) from each of the three views.
        // (Both i64, so that neither is widened on the common path.)
        let in_sram = self.b.create_block();
        self.b.append_block_param(in_sram, types::I64);
        self.b.append_block_param(in_sram, types::I64);
        // Past the confined code's bank check.
        let in_sram_ok = self.b.create_block();
        self.b.append_block_param(in_sram_ok, types::I64);
        self.b.append_block_param(in_sram_ok, types::I64);
        let join = self.b.create_block();
        self.b.append_block_param(join, types::I32);
        if !solo {
            self.b.append_block_param(join, types::I64);
        }
        // The common cases first, each in one comparison: aligned and in the striped view,
        // or aligned and in the non-striped alias of SRAM0-3 (bank = bits 17:16; where the
        // firmware images keep each core's data) — the alias first in a region fetched
        // through the alias. The offset into the view rotated right by log2(size) moves
        // the low (alignment) bits to the top, so it is below `0x40000 >> log2(size)`
        // exactly when the offset is below 0x40000 and a multiple of the size.
        let off = self.b.ins().iadd_imm_s(addr, -(SRAM_BASE as i64));
        let shift = size.trailing_zeros() as i64;
        // Confined code allowed exactly one of SRAM0-3: first that bank through the alias,
        // in one comparison that is the view, the alignment and the bank check at once
        // (its bank offset a constant).
        let own = self
            .confined
            .map(|c| c.mask & 0xf)
            .filter(|a| a.count_ones() == 1);
        if let Some(a) = own {
            let bank = a.trailing_zeros();
            let rel = self
                .b
                .ins()
                .iadd_imm_s(addr, -((SRAM_ALIAS_BASE + (bank << 16)) as i64));
            let next = self.in_view(rel, shift, 0x1_0000);
            // Word w of bank b is at physical offset (4w + b)·4.
            let word = self.b.ins().band_imm_u(rel, 0xfffc);
            let phys = self.b.ins().iadd_imm_s(word, bank as i64);
            let phys = self.b.ins().ishl_imm_u(phys, 2);
            let phys = if size < 4 {
                let low = self.b.ins().band_imm_u(rel, 3);
                self.b.ins().bor(phys, low)
            } else {
                phys
            };
            let phys = self.b.ins().uextend(types::I64, phys);
            let boff = self.b.ins().iconst(types::I64, 16 * bank as i64);
            self.b
                .ins()
                .jump(in_sram_ok, &[BlockArg::Value(phys), BlockArg::Value(boff)]);
            self.b.switch_to_block(next);
        }
        let order = if self.alias_first {
            [true, false]
        } else {
            [false, true]
        };
        for alias in order {
            let rel = if alias {
                self.b.ins().iadd_imm_s(addr, -(SRAM_ALIAS_BASE as i64))
            } else {
                off
            };
            let next = self.in_view(rel, shift, 0x4_0000);
            let phys = if alias {
                let bank = self.b.ins().ushr_imm_u(rel, 16);
                let word = self.b.ins().band_imm_u(rel, 0xfffc);
                let phys = self.b.ins().iadd(word, bank);
                let phys = self.b.ins().ishl_imm_u(phys, 2);
                // (A word access is aligned here: its low bits are zero.)
                if size < 4 {
                    let low = self.b.ins().band_imm_u(rel, 3);
                    self.b.ins().bor(phys, low)
                } else {
                    phys
                }
            } else {
                rel
            };
            // The bank from the physical (striped) offset.
            let phys = self.b.ins().uextend(types::I64, phys);
            let boff = self.striped_bank_offset(phys);
            self.b
                .ins()
                .jump(in_sram, &[BlockArg::Value(phys), BlockArg::Value(boff)]);
            self.b.switch_to_block(next);
        }
        // Unaligned: the general path; aligned: SRAM4/5 (the striped view's end: `off` is
        // at least 0x40000 here), flash.
        if size > 1 {
            let low = self.b.ins().band_imm_u(addr, size as i64 - 1);
            self.general_if(low, pc);
        }
        let scratch = self.b.create_block();
        let elsewhere = self.b.create_block();
        self.b.set_cold_block(elsewhere);
        let ok = self
            .b
            .ins()
            .icmp_imm_u(IntCC::UnsignedLessThan, off, SRAM_SIZE as i64);
        self.b.ins().brif(ok, scratch, &[], elsewhere, &[]);
        self.b.switch_to_block(scratch);
        let off64 = self.b.ins().uextend(types::I64, off);
        let boff = self.scratch_bank_offset(off64);
        self.b
            .ins()
            .jump(in_sram, &[BlockArg::Value(off64), BlockArg::Value(boff)]);
        self.b.switch_to_block(elsewhere);
        if op.is_store() {
            if size == 4 {
                if self.confined.is_some_and(|c| c.io) {
                    self.io_reg(rt, addr, join, solo, pc);
                }
                self.ppb_store(ins, rt, addr);
            }
            let p = self.c32(pc);
            self.leave(p, Exit::General);
        } else {
            let f = self.b.ins().iadd_imm_s(addr, -(FLASH_BASE as i64));
            let ok = self
                .b
                .ins()
                .icmp_imm_u(IntCC::UnsignedLessThan, f, FLASH_SIZE as i64);
            let in_flash = self.b.create_block();
            self.b.set_cold_block(in_flash);
            let out = self.b.create_block();
            self.b.set_cold_block(out);
            self.b.ins().brif(ok, in_flash, &[], out, &[]);
            self.b.switch_to_block(out);
            if size == 4 {
                self.ppb_load(ins, rt, addr);
            }
            let p = self.c32(pc);
            self.leave(p, Exit::General);
            self.b.switch_to_block(in_flash);
            let f64_ = self.b.ins().uextend(types::I64, f);
            let flash = self.ctx_ptr(offset_of!(Ctx, flash));
            let at = self.b.ins().iadd(flash, f64_);
            let v = self.load_sized(op, at);
            let mut args = vec![BlockArg::Value(v)];
            if !solo {
                let zero = self.b.ins().iconst(types::I64, 0);
                args.push(BlockArg::Value(zero));
            }
            self.b.ins().jump(join, &args);
        }
        // SRAM: the arbiter, then the data.
        self.b.switch_to_block(in_sram);
        let off = self.b.block_params(in_sram)[0];
        let boff = self.b.block_params(in_sram)[1];
        let args = [BlockArg::Value(off), BlockArg::Value(boff)];
        match self.confined {
            Some(c) if c.io => {
                // An allowed bank, or one of the I/O's whose accesses are logged.
                let allowed = self.allowed(c);
                let (bank, bit) = self.bank_bit(allowed, boff);
                let ok = self.b.ins().band_imm_u(bit, 1);
                let io = self.b.create_block();
                self.b.set_cold_block(io);
                self.b.ins().brif(ok, in_sram_ok, &args, io, &[]);
                self.b.switch_to_block(io);
                self.io_sram(op, rt, pc, off, bank);
                self.b.ins().jump(in_sram_ok, &args);
            }
            Some(_) => {
                self.confine_banks(ins, &[boff]);
                self.b.ins().jump(in_sram_ok, &args);
            }
            None => {
                self.b.ins().jump(in_sram_ok, &args);
            }
        }
        self.b.switch_to_block(in_sram_ok);
        let off = self.b.block_params(in_sram_ok)[0];
        let boff = self.b.block_params(in_sram_ok)[1];
        self.journal(&[(off, boff)], op.is_store(), op.size() == 4);
        let c = self.b.use_var(self.cyc);
        let at = self.b.ins().iadd_imm_s(c, 1);
        let wait = self.arbitrate(boff, at);
        let off64 = off;
        let p = self.b.ins().iadd(self.sram, off64);
        let first = if op.is_store() {
            let v = self.reg(rt, pc);
            match size {
                1 => self.b.ins().istore8(self.mf, v, p, 0),
                2 => self.b.ins().istore16(self.mf, v, p, 0),
                _ => self.b.ins().store(self.mf, v, p, 0),
            };
            let page = self.b.ins().ushr_imm_u(off64, 8);
            let code_pages = self.ctx_ptr(offset_of!(Ctx, code_pages));
            let pp = self.b.ins().iadd(code_pages, page);
            self.b.ins().uload8(types::I32, self.mf, pp, 0)
        } else {
            self.load_sized(op, p)
        };
        let mut args = vec![BlockArg::Value(first)];
        args.extend(wait.map(BlockArg::Value));
        self.b.ins().jump(join, &args);
        self.b.switch_to_block(join);
        let v = self.b.block_params(join)[0];
        let wait = (!solo).then(|| self.b.block_params(join)[1]);
        if !op.is_store() {
            self.set(rt, v);
        }
        self.retire(ins.cost.0, wait);
        if op.is_store() {
            self.invalidate_if(v, ins);
        }
        true
    }

    /// The signature of a Rust helper the native code calls (`extern "C"`, the host's
    /// calling convention): `params`, and `ret` when it returns a value.
    fn helper_signature(
        &mut self,
        params: &[types::Type],
        ret: Option<types::Type>,
    ) -> cranelift_codegen::ir::SigRef {
        let mut s = Signature::new(self.b.func.signature.call_conv);
        s.params.extend(params.iter().map(|&t| AbiParam::new(t)));
        s.returns.extend(ret.map(AbiParam::new));
        self.b.import_signature(s)
    }

    /// Confined code, an SRAM access `op` of `rt` by the instruction at `pc` at physical
    /// offset `off` (i64) in bank `bank` (i32) that the bank mask does not allow: leaves
    /// before the instruction unless the bank is one of the I/O's whose accesses native
    /// code logs ([`Ctx::io_banks`]); then logs it ([`io_sram`]), and the caller does it
    /// as in an allowed bank.
    fn io_sram(&mut self, op: MemOp, rt: u8, pc: u32, off: Value, bank: Value) {
        let at = offset_of!(Ctx, io_banks) as i32;
        let banks = self.b.ins().load(types::I32, self.mf, self.ctx, at);
        let bit = self.b.ins().ushr(banks, bank);
        let logged = self.b.ins().band_imm_u(bit, 1);
        self.general_unless(logged, pc);
        let start = self.b.use_var(self.cyc);
        let kind = op.size() as i64 | i64::from(op.is_store()) << 8;
        let packed = self.b.ins().ishl_imm_u(off, 32);
        let packed = self.b.ins().bor_imm_u(packed, kind);
        let value = match op.is_store() {
            true => self.reg(rt, pc),
            false => self.c32(0),
        };
        let sig = self.helper_signature(&[types::I64, types::I64, types::I64, types::I32], None);
        let f = self
            .b
            .ins()
            .iconst(types::I64, io_sram as *const () as usize as i64);
        self.b
            .ins()
            .call_indirect(sig, f, &[self.ctx, start, packed, value]);
    }

    /// Confined code, a word store of `rt` to `addr` (not SRAM: the builder in the block
    /// that found it so) by the instruction at `pc`: for an address in the APB/AHB
    /// peripherals' range (0x5xxxxxxx), calls [`io_reg`], and when it logged the store for
    /// the I/O's replay, goes on at `join` (no wait, no code page; `solo`: `join` takes no
    /// wait); otherwise leaves the builder in a block that goes on as before.
    fn io_reg(
        &mut self,
        rt: u8,
        addr: Value,
        join: cranelift_codegen::ir::Block,
        solo: bool,
        pc: u32,
    ) {
        let top = self.b.ins().ushr_imm_u(addr, 28);
        let peripheral = self.b.ins().icmp_imm_u(IntCC::Equal, top, 5);
        let call = self.b.create_block();
        self.b.set_cold_block(call);
        let next = self.b.create_block();
        self.b.set_cold_block(next);
        self.b.ins().brif(peripheral, call, &[], next, &[]);
        self.b.switch_to_block(call);
        let start = self.b.use_var(self.cyc);
        let value = self.reg(rt, pc);
        let sig = self.helper_signature(
            &[types::I64, types::I64, types::I32, types::I32],
            Some(types::I32),
        );
        let f = self
            .b
            .ins()
            .iconst(types::I64, io_reg as *const () as usize as i64);
        let r = self
            .b
            .ins()
            .call_indirect(sig, f, &[self.ctx, start, addr, value]);
        let done = self.b.inst_results(r)[0];
        let mut args = vec![BlockArg::Value(self.c32(0))];
        if !solo {
            let zero = self.b.ins().iconst(types::I64, 0);
            args.push(BlockArg::Value(zero));
        }
        self.b.ins().brif(done, join, &args, next, &[]);
        self.b.switch_to_block(next);
    }

    /// The private peripheral bus for a word load at `addr` by `ins` into `rt` (not SRAM
    /// nor flash; the builder in the block that found it so): when `addr` is in the PPB,
    /// calls [`ppb_load`] and, when it did the load, completes the instruction (no wait)
    /// and leaves the region after it ([`Exit::Out`]), so that the runner looks at the
    /// next address afresh (a memoized span may start there: the firmware images' sample
    /// interrupt memoizes its keys from the SYST_RVR store to the ICSR load); otherwise
    /// leaves the builder in a block that goes on to the general path. Confined code only:
    /// a window's core runs with its interrupt lines already pending, as the executor's
    /// general step would make them (see [`crate::board`]'s windows).
    fn ppb_load(&mut self, ins: &RegionInstr, rt: u8, addr: Value) {
        if self.confined.is_none() {
            return;
        }
        let on_ppb =
            self.b
                .ins()
                .icmp_imm_u(IntCC::UnsignedGreaterThanOrEqual, addr, PPB_BASE as i64);
        let f = ppb_load as *const ();
        let (r, general) = self.ppb_call(on_ppb, f, addr, types::I64);
        let done = self.b.ins().ushr_imm_u(r, 32);
        let v = self.b.ins().ireduce(types::I32, r);
        self.ppb_complete(ins, done, general, Some((rt, v)));
    }

    /// As [`Translator::ppb_load`] for a word store of `rt` to [`SYST_RVR`] ([`ppb_store`]).
    fn ppb_store(&mut self, ins: &RegionInstr, rt: u8, addr: Value) {
        if self.confined.is_none() {
            return;
        }
        let is_rvr = self.b.ins().icmp_imm_u(IntCC::Equal, addr, SYST_RVR as i64);
        let value = self.reg(rt, ins.pc);
        let f = ppb_store as *const ();
        let (done, general) = self.ppb_call(is_rvr, f, value, types::I32);
        self.ppb_complete(ins, done, general, None);
    }

    /// When `take` holds, calls the helper `f` (`extern "C" fn(core, at, x) -> ret`, as
    /// [`ppb_load`] and [`ppb_store`]) with the access's data-phase cycle (`cyc + 1`, as
    /// the SRAM path's) and `x`; returns its result, the builder in the calling block, and
    /// the block where the general path goes on (`take` false, or the helper did nothing).
    fn ppb_call(
        &mut self,
        take: Value,
        f: *const (),
        x: Value,
        ret: types::Type,
    ) -> (Value, cranelift_codegen::ir::Block) {
        let call = self.b.create_block();
        self.b.set_cold_block(call);
        let general = self.b.create_block();
        self.b.set_cold_block(general);
        self.b.ins().brif(take, call, &[], general, &[]);
        self.b.switch_to_block(call);
        let c = self.b.use_var(self.cyc);
        let at = self.b.ins().iadd_imm_s(c, 1);
        let sig = self.helper_signature(&[types::I64, types::I64, types::I32], Some(ret));
        let f = self.b.ins().iconst(types::I64, f as usize as i64);
        let r = self.b.ins().call_indirect(sig, f, &[self.core, at, x]);
        (self.b.inst_results(r)[0], general)
    }

    /// After [`Translator::ppb_call`]: when `done` is non-zero, sets the loaded register
    /// (`load`), completes `ins` and leaves after it ([`Translator::complete_and_leave`]);
    /// the builder ends in `general`.
    fn ppb_complete(
        &mut self,
        ins: &RegionInstr,
        done: Value,
        general: cranelift_codegen::ir::Block,
        load: Option<(u8, Value)>,
    ) {
        let complete = self.b.create_block();
        self.b.set_cold_block(complete);
        self.b.ins().brif(done, complete, &[], general, &[]);
        self.b.switch_to_block(complete);
        if let Some((rt, v)) = load {
            self.set(rt, v);
        }
        self.complete_and_leave(ins);
        self.b.switch_to_block(general);
    }

    /// In a side block: retires `ins` (its static cycles, no wait) and leaves the region
    /// at the next instruction ([`Exit::Out`]); the straight-line counts pending for the
    /// code after `ins` on the main path stay as they were.
    fn complete_and_leave(&mut self, ins: &RegionInstr) {
        let pending = (self.pend_cyc, self.pend_n);
        self.retire(ins.cost.0, None);
        let next = self.c32(ins.pc.wrapping_add(ins.size));
        self.leave(next, Exit::Out);
        (self.pend_cyc, self.pend_n) = pending;
    }

    /// After a store: leaves with [`Exit::Invalidate`] when it hit a code page.
    pub(super) fn invalidate_if(&mut self, code: Value, ins: &RegionInstr) {
        let out = self.b.create_block();
        self.b.set_cold_block(out);
        let on = self.b.create_block();
        self.flush();
        self.b.ins().brif(code, out, &[], on, &[]);
        self.b.switch_to_block(out);
        let p = self.c32(ins.pc.wrapping_add(ins.size));
        self.leave(p, Exit::Invalidate);
        self.b.switch_to_block(on);
    }

    pub(super) fn load_sized(&mut self, op: MemOp, p: Value) -> Value {
        let mf = self.mf;
        match op {
            MemOp::Ldrb => self.b.ins().uload8(types::I32, mf, p, 0),
            MemOp::Ldrsb => self.b.ins().sload8(types::I32, mf, p, 0),
            MemOp::Ldrh => self.b.ins().uload16(types::I32, mf, p, 0),
            MemOp::Ldrsh => self.b.ins().sload16(types::I32, mf, p, 0),
            _ => self.b.ins().load(types::I32, mf, p, 0),
        }
    }

    /// `count` consecutive words from `start` (PUSH, POP, STM, LDM: `push_fast`,
    /// `pop_fast` and the `Stm`/`Ldm` arms of `execute_fast`): all in the striped view or
    /// SRAM4/5 and word-aligned, else it leaves before the instruction. Stores `values`,
    /// or loads the words; with `pops_pc`, a PC word that would leave Thumb state or return
    /// from an exception leaves before the instruction. Returns the loaded words, the
    /// wait states (`None` in [`Flavour::Solo`](super::Flavour::Solo) code: none) and whether a store hit a code
    /// page; the caller retires it.
    pub(super) fn multiple(
        &mut self,
        ins: &RegionInstr,
        start: Value,
        count: u32,
        values: Option<&[Value]>,
        pops_pc: bool,
    ) -> (Vec<Value>, Option<Value>, Value) {
        let pc = ins.pc;
        self.flush();
        let off = self.b.ins().iadd_imm_s(start, -(SRAM_BASE as i64));
        let low = self.b.ins().band_imm_u(start, 3);
        let too_far = self.b.ins().icmp_imm_u(
            IntCC::UnsignedGreaterThan,
            off,
            (SRAM_SIZE - 4 * count) as i64,
        );
        let too_far = too_far.into_i32(&mut self.b);
        let bad = self.b.ins().bor(low, too_far);
        self.general_if(bad, pc);
        let off64 = self.b.ins().uextend(types::I64, off);
        let base_p = self.b.ins().iadd(self.sram, off64);
        if pops_pc {
            let t = self
                .b
                .ins()
                .load(types::I32, self.mf, base_p, 4 * (count as i32 - 1));
            let bad = self.interworking_exit(t, true);
            self.general_if(bad, pc);
        }
        let striped = self
            .b
            .ins()
            .icmp_imm_u(IntCC::UnsignedLessThan, off, 0x4_0000);
        let words: Vec<(Value, Value)> = (0..count)
            .map(|k| {
                let o = self.b.ins().iadd_imm_s(off, 4 * k as i64);
                (o, self.bank_offset(o, Some(striped)))
            })
            .collect();
        self.confine(ins, &words, values.is_some(), true);
        let c = self.b.use_var(self.cyc);
        let mut at = self.b.ins().iadd_imm_s(c, 1);
        let mut total = None;
        let mut loaded = Vec::new();
        let mut code = self.b.ins().iconst(types::I32, 0);
        // Loaded once for the transfer's stores (not held through the region).
        let code_pages = values
            .is_some()
            .then(|| self.ctx_ptr(offset_of!(Ctx, code_pages)));
        for k in 0..count {
            let (o, boff) = words[k as usize];
            at = match self.arbitrate(boff, at) {
                Some(wait) => {
                    total = Some(match total {
                        None => wait,
                        Some(t) => self.b.ins().iadd(t, wait),
                    });
                    let step = self.b.ins().iadd_imm_s(wait, 1);
                    self.b.ins().iadd(at, step)
                }
                None => self.b.ins().iadd_imm_s(at, 1),
            };
            match values.zip(code_pages) {
                Some((vs, code_pages)) => {
                    self.b
                        .ins()
                        .store(self.mf, vs[k as usize], base_p, 4 * k as i32);
                    let o64 = self.b.ins().uextend(types::I64, o);
                    let page = self.b.ins().ushr_imm_u(o64, 8);
                    let pp = self.b.ins().iadd(code_pages, page);
                    let hit = self.b.ins().uload8(types::I32, self.mf, pp, 0);
                    code = self.b.ins().bor(code, hit);
                }
                None => {
                    let v = self.b.ins().load(types::I32, self.mf, base_p, 4 * k as i32);
                    loaded.push(v);
                }
            }
        }
        (loaded, total, code)
    }
}

/// `icmp` results are `i8`; widen one to `i32` to combine it with a word.
trait IntoI32 {
    fn into_i32(self, b: &mut FunctionBuilder) -> Value;
}

impl IntoI32 for Value {
    fn into_i32(self, b: &mut FunctionBuilder) -> Value {
        b.ins().uextend(types::I32, self)
    }
}
