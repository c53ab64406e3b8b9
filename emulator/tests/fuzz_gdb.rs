//! Fuzz: random and truncated GDB remote-protocol traffic against the stub
//! (`tactus_emulator::debug::gdb`). Each case connects a client over 127.0.0.1, sends a
//! mix of well-formed packets (registers, memory, breakpoints, watchpoints, steps, continue,
//! Ctrl-C, monitor commands) and edited bytes (checksums broken, packets cut, bytes set,
//! repeated), then goes away. The board must reach its cycle limit, the stub must never
//! panic, and a client that only reads must not change the run: the final cycles and
//! registers equal those of the run without a debugger. `TACTUS_FUZZ_CASES=100000` for a
//! long run.

#[path = "../../tests/common/fuzz.rs"]
mod fuzz;

use proptest::prelude::*;
use std::io::{Read, Write};
use std::time::Duration;
use tactus_emulator::debug::gdb::{listen, GdbSession};
use tactus_emulator::{Board, Config};

/// A two-core program: core 0 counts in r0 and stores it at 0x20001000 in a loop, with
/// a call and a push/pop; core 1 is left parked.
fn board() -> Board {
    let mut b = Board::new(Config::default());
    // 0x20000000: movs r0,#0; ldr r1,[pc,#8]; loop: adds r0,#1; str r0,[r1]; push {r0};
    // pop {r2}; b loop; .word 0x20001000
    let code: [u16; 8] = [
        0x2000, 0x4903, 0x3001, 0x6008, 0xb401, 0xbc04, 0xe7fa, 0x0000,
    ];
    let bytes: Vec<u8> = code.iter().flat_map(|h| h.to_le_bytes()).collect();
    b.write_bytes(0x2000_0000, &bytes).unwrap();
    b.write_bytes(0x2000_0010, &0x2000_1000u32.to_le_bytes())
        .unwrap();
    b.start_core(0, 0x2000_0000, 0x2002_0000, 0x2000_0000);
    b
}

const LIMIT: u64 = 40_000;

fn packet(body: &str) -> Vec<u8> {
    let sum = body.bytes().fold(0u8, |a, b| a.wrapping_add(b));
    format!("${body}#{sum:02x}").into_bytes()
}

/// Well-formed packets that only read (or set breakpoints and watchpoints, which do not
/// change the run).
const READS: &[&str] = &[
    "?",
    "g",
    "qSupported:multiprocess+;swbreak+;hwbreak+;qRelocInsn+;vContSupported+",
    "qfThreadInfo",
    "qsThreadInfo",
    "Hg2",
    "Hg1",
    "Hc-1",
    "m20000000,10",
    "m20001000,4",
    "m00000000,40",
    "m40000000,8",
    "mffffffff,10",
    "p0",
    "p10",
    "p14",
    "p99",
    "Z0,20000004,2",
    "z0,20000004,2",
    "Z1,20000008,2",
    "Z2,20001000,4",
    "Z3,20001000,4",
    "Z4,20001000,4",
    "z2,20001000,4",
    "vCont?",
    "vCont;s:1;c",
    "vCont;s:2",
    "vCont;c",
    "c",
    "s",
    "qRcmd,6379636c6573",
    "qRcmd,68656c70",
    "qRcmd,",
    "T1",
    "T3",
    "qXfer:features:read:target.xml:0,400",
    "qThreadExtraInfo,1",
    "qC",
    "qAttached",
    "vMustReplyEmpty",
    "QStartNoAckMode",
    "D",
];

/// Packets that change the program (registers, memory).
const WRITES: &[&str] = &[
    "M20001000,4:01020304",
    "Gxx",
    "P0=01000000",
    "X20001000,0:",
    "M0,1:00",
    "P10=00000000",
    "k",
];

#[derive(Clone, Debug)]
enum Piece {
    Packet(usize, bool),
    Interrupt,
    Ack,
    Raw(Vec<u8>),
}

fn piece() -> impl Strategy<Value = Piece> {
    prop_oneof![
        8 => (any::<usize>(), any::<bool>()).prop_map(|(i, w)| Piece::Packet(i, w)),
        1 => Just(Piece::Interrupt),
        2 => Just(Piece::Ack),
        2 => prop::collection::vec(any::<u8>(), 0..40).prop_map(Piece::Raw),
    ]
}

fn bytes(pieces: &[Piece], writes: bool) -> Vec<u8> {
    let mut v = Vec::new();
    for p in pieces {
        match p {
            Piece::Packet(i, w) => {
                let list = if *w && writes { WRITES } else { READS };
                v.extend(packet(list[i % list.len()]));
            }
            Piece::Interrupt => v.push(0x03),
            Piece::Ack => v.push(b'+'),
            Piece::Raw(r) => {
                if writes {
                    v.extend(r)
                }
            }
        }
    }
    v
}

/// A board's final state as the tests compare it: both cores' cycles, then each core's
/// registers.
type Final = ([u64; 2], [u32; 16], [u32; 16]);

/// Runs the board under a session fed `input`; the client reads what the stub says (so
/// it never blocks on a full socket) and leaves when its input is sent. Returns the
/// board's final cycles and registers, or None if the run did not end in time.
fn run_with_client(input: Vec<u8>) -> Option<(Final, usize)> {
    let listener = listen(0).ok()?;
    let addr = listener.local_addr().ok()?;
    let client = std::thread::spawn(move || {
        let mut heard = 0;
        if let Ok(mut s) = std::net::TcpStream::connect(addr) {
            let _ = s.set_read_timeout(Some(Duration::from_millis(2)));
            let mut sink = [0u8; 4096];
            for chunk in input.chunks(7) {
                if s.write_all(chunk).is_err() {
                    break;
                }
                heard += s.read(&mut sink).unwrap_or(0);
            }
            let _ = s.shutdown(std::net::Shutdown::Both);
        }
        heard
    });
    let (conn, _) = listener.accept().ok()?;
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut b = board();
        b.attach_debugger(Box::new(GdbSession::new(conn, Box::new(|_| {}))));
        // A client that writes registers may leave a core faulted or locked up: then the
        // run ends there.
        for _ in 0..1000 {
            if b.cycle() >= LIMIT || b.run_until(LIMIT) != tactus_emulator::StopReason::CycleLimit {
                break;
            }
        }
        b.finish_debugging();
        let _ = tx.send((
            [b.cores[0].cycle, b.cores[1].cycle],
            b.cores[0].r,
            b.cores[1].r,
        ));
    });
    let r = rx.recv_timeout(Duration::from_secs(30)).ok();
    let heard = client.join().unwrap_or(0);
    r.map(|r| (r, heard))
}

#[test]
fn random_and_truncated_rsp_packets_never_panic_or_hang() {
    let plain = {
        let mut b = board();
        b.run_until(LIMIT);
        (
            [b.cores[0].cycle, b.cores[1].cycle],
            b.cores[0].r,
            b.cores[1].r,
        )
    };
    let (mut runner, cases) = fuzz::runner(64);
    let replies = std::cell::Cell::new(0usize);
    let strategy = (
        prop::collection::vec(piece(), 0..24),
        any::<bool>(),
        fuzz::edits(&[b"$", b"#", b"#00", b"}", b"*", b"\x03", b"$m", b"$Z0,"]),
    );
    runner
        .run(&strategy, |(pieces, writes, edits)| {
            let mut input = bytes(&pieces, writes);
            let edited = writes && !edits.is_empty();
            if edited {
                input = fuzz::apply(&input, &edits);
            }
            let got = run_with_client(input);
            prop_assert!(got.is_some(), "the debugged run did not end within 30 s");
            let (end, heard) = got.unwrap();
            replies.set(replies.get() + heard);
            if !writes {
                prop_assert_eq!(end, plain, "a reading client changed the run");
            }
            Ok(())
        })
        .unwrap();
    // The stub answered (acks, stop replies, registers): the sessions were real.
    assert!(replies.get() > 0, "the stub never answered");
    println!("{cases} sessions, {} bytes of replies", replies.get());
}
