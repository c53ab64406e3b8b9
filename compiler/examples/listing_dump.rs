// Scratch (not committed).
fn main() {
    let text = std::fs::read_to_string("instruments/grand_piano.tactus").unwrap();
    let p = tactus_compiler::compile(&text, &Default::default()).unwrap().program;
    let fp = tactus_compiler::fixed::FixedProgram::new(&p);
    let obj = tactus_compiler::thumb::compile(&fp).unwrap();
    std::fs::write("/tmp/piano16.s", &obj.code.listing).unwrap();
    std::fs::write("/tmp/piano16.bin", &obj.code.text).unwrap();
}
