//! State words read back right after their store: the semi-implicit Euler step stores a
//! velocity and reads it again for the position (`w' = …; s' = w`), and the IR reads the
//! state afresh. Where the load follows the store in straight-line code (no label between,
//! so every way to the load passes the store), with no other store that may write the word
//! and no redefinition of the stored register between, the load becomes a copy of that
//! register (`MOV`, which the allocator removes when the stored register ends there): the
//! word in memory is the register's, stored unchanged.

use super::mir::*;
use tactus_emulator::decode::MemOp;

/// Instructions searched after a store for a load of the same word.
const WINDOW: usize = 24;

/// Replaces loads of a state word just stored (see the module comment) by copies.
pub(crate) fn forward(code: &mut [M]) {
    for i in 0..code.len() {
        let M::Store {
            op: MemOp::Str,
            t,
            base: Base::State,
            off,
        } = code[i]
        else {
            continue;
        };
        for j in i + 1..code.len().min(i + 1 + WINDOW) {
            match code[j] {
                M::Load {
                    op: MemOp::Ldr,
                    t: d,
                    base: Base::State,
                    off: o,
                } if o == off => {
                    code[j] = M::Mov { d, s: t };
                    break;
                }
                // Control may arrive here from elsewhere, or leave.
                M::Label(_) | M::B(_) | M::Bc(..) => break,
                // Another store that may write the word (at an unknown address, or this one).
                M::Store {
                    base: Base::State,
                    off: o,
                    ..
                } if o / 4 == off / 4 => break,
                M::Store {
                    base: Base::V(b), ..
                } if b != super::select::ARG2 => break,
                M::StoreR { .. } => break,
                ref m if m.def() == Some(t) => break,
                _ => {}
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn store(t: u32, off: u16) -> M {
        M::Store {
            op: MemOp::Str,
            t: V(t),
            base: Base::State,
            off,
        }
    }

    fn load(t: u32, off: u16) -> M {
        M::Load {
            op: MemOp::Ldr,
            t: V(t),
            base: Base::State,
            off,
        }
    }

    /// A load right after the store of its word copies the stored register (the last
    /// store's, when two write it); a label, a branch or a redefinition of the stored
    /// register in between keeps the load.
    #[test]
    fn forwards_only_through_straight_line_code() {
        let mut code = vec![store(3, 16), load(4, 8), load(5, 16)];
        forward(&mut code);
        assert_eq!(code[1], load(4, 8));
        assert_eq!(code[2], M::Mov { d: V(5), s: V(3) });
        let mut code = vec![store(3, 16), store(6, 16), load(5, 16)];
        forward(&mut code);
        assert_eq!(code[2], M::Mov { d: V(5), s: V(6) });
        for between in [
            M::Label(Label(0)),
            M::Movi { d: V(3), imm: 1 },
            M::Bc(Cond::Eq, Label(1)),
        ] {
            let mut code = vec![store(3, 16), between.clone(), load(5, 16)];
            forward(&mut code);
            assert_eq!(code[2], load(5, 16), "{between:?}");
        }
    }
}
