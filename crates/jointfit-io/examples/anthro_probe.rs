fn main() {
    for a in std::env::args().skip(1) {
        let model = jointfit_io::model_file::load_model(&a).unwrap();
        for m in jointfit::plausibility::anthropometry(&model, &model.nominal_params()) {
            println!("{a}: {} {:.1} ok={}", m.what, m.value, m.ok());
        }
    }
}
