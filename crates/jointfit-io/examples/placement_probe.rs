use jointfit::ik::MarkerMap;
use jointfit::trial::up_axis_rotation;
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let model = jointfit_io::model_file::load_model(&a[1]).unwrap();
    let mut trial = jointfit_io::trial_file::read_trial(std::path::Path::new(&a[2])).unwrap();
    if let Some(up) = model.spec().lab_up {
        trial.rotate(&up_axis_rotation(up));
    }
    let (map, _) = MarkerMap::allowing_absent(&model, trial.labels());
    let p = jointfit::placement::compare(&model, &trial, &map);
    let segs: Vec<String> = p
        .segments
        .iter()
        .map(|s| {
            format!(
                "{}:{:.3}/{:+.0}mm/{}",
                s.segment,
                s.ratio,
                s.change * 1e3,
                s.pairs.len()
            )
        })
        .collect();
    let mut ms: Vec<_> = p
        .markers
        .iter()
        .map(|m| (m.marker.clone(), m.change))
        .collect();
    ms.sort_by(|x, y| y.1.total_cmp(&x.1));
    let top: Vec<String> = ms
        .iter()
        .take(4)
        .map(|(m, c)| format!("{m}:{:.0}", c * 1e3))
        .collect();
    println!(
        "ratio {:.3} | {} | top {} | {:?}",
        p.ratio,
        segs.join(" "),
        top.join(" "),
        p.mismatch().map(|m| m.cause())
    );
}
