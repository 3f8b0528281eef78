//! The parsers never panic, whatever the input.

use phalanx_core::Grid;
use phalanx_io::{MovingAiMap, Scenario, YamlInstance, YamlPlan, instance_from_scen};
use proptest::prelude::*;

fn all_parsers(text: &str) {
    if let Ok(map) = MovingAiMap::parse(text) {
        let _ = map.to_grid();
    }
    if let Ok(scen) = Scenario::parse(text) {
        let _ = instance_from_scen(Grid::new(4, 4), &scen, scen.entries.len());
    }
    if let Ok(inst) = YamlInstance::parse(text) {
        let _ = inst.to_instance();
    }
    if let Ok(plan) = YamlPlan::parse(text) {
        let _ = plan.to_plan(&["agent0".to_owned()]);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        all_parsers(&String::from_utf8_lossy(&bytes));
    }

    #[test]
    fn format_like_text_never_panics(text in "(type octile\n|height [0-9]{1,2}\n|width [0-9]{1,2}\nmap\n|version 1\n|[.@TGW#]{0,5}\n|[0-9 \t]{0,12}m.map[0-9 \t.-]{0,20}\n|map:\n|  dimensions: \\[[0-9-]{1,3}, [0-9]{1,2}\\]\n|agents:\n|- name: a\n|  start: \\[[0-9-]{1,2}, [0-9]\\]\n|  goal: \\[[0-9], [0-9]\\]\n|schedule:\n|  agent0:\n|    - \\{x: [0-9], y: [0-9], t: [0-9]\\}\n){0,12}") {
        all_parsers(&text);
    }
}
