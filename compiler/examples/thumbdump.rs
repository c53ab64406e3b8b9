fn main() {
    let f = std::env::args().nth(1).unwrap();
    let src = std::fs::read_to_string(&f).unwrap();
    let p = tactus_compiler::compile(&src, &Default::default())
        .unwrap()
        .program;
    let fp = tactus_compiler::fixed::FixedProgram::new(&p);
    let o = tactus_compiler::thumb::compile(&fp).unwrap();
    print!("{}", o.code.listing);
}
