fn main() {
    let path = std::env::args().nth(1).unwrap();
    let src = std::fs::read_to_string(&path).unwrap();
    match tactus_compiler::compile(&src, &Default::default()) {
        Ok(l) => { println!("{}", l.program); print!("{}", tactus_compiler::diagnostics::emit_to_string(&path, &src, &l.warnings)); }
        Err(d) => print!("{}", tactus_compiler::diagnostics::emit_to_string(&path, &src, &d)),
    }
}
