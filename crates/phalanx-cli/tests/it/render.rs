//! `phalanx render`, `solve --render` and `phalanx demo`, whose page a headless Chromium
//! opens and photographs as a person would look at it.

use std::path::Path;
use std::process::Command;

use super::{check, phalanx};

#[test]
fn render_draws_every_format_and_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = ["gen", "--size", "16", "--density", "0.1", "--agents", "3", "--seed", "2"];
    check(&phalanx(d, &[&args[..], &["-o", "inst.yaml"]].concat()), 0);
    let solve = ["solve", "inst.yaml", "--planner", "swarm", "-o", "plan.yaml"];
    check(&phalanx(d, &[&solve[..], &["--render", "solve.gif"]].concat()), 0);
    assert_eq!(&std::fs::read(d.join("solve.gif")).unwrap()[..6], b"GIF89a");

    for (file, magic) in [("a.svg", &b"<svg"[..]), ("a.gif", b"GIF89a"), ("a.png", b"\x89PNG")] {
        let (stdout, _) = check(&phalanx(d, &["render", "inst.yaml", "plan.yaml", "-o", file]), 0);
        assert!(stdout.contains(file), "{stdout}");
        assert!(std::fs::read(d.join(file)).unwrap().starts_with(magic), "{file}");
    }
    let still = ["render", "inst.yaml", "plan.yaml", "-o", "s.svg", "--step", "2", "--no-fov"];
    check(&phalanx(d, &still), 0);
    let svg = std::fs::read_to_string(d.join("s.svg")).unwrap();
    assert!(!svg.contains("<animate"), "a still does not move");

    let (_, err) = check(&phalanx(d, &["render", "inst.yaml", "plan.yaml", "-o", "a.jpg"]), 2);
    assert!(err.contains("a.jpg") && err.contains(".svg, .gif or .png"), "{err}");
    let late = ["render", "inst.yaml", "plan.yaml", "-o", "b.png", "--step", "999"];
    let (_, err) = check(&phalanx(d, &late), 2);
    assert!(err.contains("--step 999") && err.contains("plan.yaml"), "{err}");
    assert!(!d.join("b.png").exists(), "nothing written");
    let (_, err) =
        check(&phalanx(d, &["render", "inst.yaml", "plan.yaml", "-o", "c.svg", "--fps", "0"]), 2);
    assert!(err.contains("--fps"), "{err}");
    let (_, err) = check(&phalanx(d, &["render", "inst.yaml", "none.yaml", "-o", "c.svg"]), 2);
    assert!(err.contains("none.yaml"), "{err}");
    let (_, err) = check(&phalanx(d, &[&solve[..], &["--render", "x.bmp"]].concat()), 2);
    assert!(err.contains("x.bmp"), "{err}");
}

/// Headless Chromium, if installed (`.ci/run` installs Debian's `chromium` and then sets
/// `PHALANX_BROWSER_CHECK=1`, with which its absence fails the test).
fn chromium() -> Option<&'static str> {
    let found = ["chromium", "chromium-browser"].into_iter().find(|name| {
        Command::new(name).arg("--version").output().is_ok_and(|out| out.status.success())
    });
    if found.is_none() {
        let required = std::env::var_os("PHALANX_BROWSER_CHECK").is_some_and(|v| v == "1");
        assert!(!required, "PHALANX_BROWSER_CHECK=1 but chromium does not run");
        #[allow(clippy::print_stderr, reason = "says why the browser check is skipped")]
        {
            eprintln!("chromium is not installed: the demo page is not opened in a browser");
        }
    }
    found
}

fn headless(browser: &str, dir: &Path, extra: &[&str], page: &Path) -> std::process::Output {
    Command::new(browser)
        .args(["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars"])
        .arg(format!("--user-data-dir={}", dir.join("profile").display()))
        .args(extra)
        .arg(format!("file://{}", page.display()))
        .output()
        .expect("running chromium")
}

#[test]
fn the_demo_page_shows_every_animation_in_a_browser() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (table, _) = check(&phalanx(d, &["demo", "--out", "demo", "--rollouts", "1"]), 0);
    // Ten runs (five methods, two instances); the planners solve both instances (a learned
    // method's greedy rollout may stop short: its best rollout is drawn all the same).
    assert_eq!(table.lines().take_while(|l| !l.is_empty()).count(), 1 + 10, "{table}");
    for planner in ["cbs", "swarm"] {
        let solved = table.lines().filter(|l| l.contains(&format!(" {planner} "))).count();
        let yes = table
            .lines()
            .filter(|l| l.contains(&format!(" {planner} ")) && l.contains(" yes "))
            .count();
        assert_eq!((solved, yes), (2, 2), "{table}");
    }
    let index = d.join("demo/index.html");
    let html = std::fs::read_to_string(&index).unwrap();
    assert_eq!(html.matches("<svg ").count(), 10);
    for case in ["generated-32", "den312d"] {
        // The shipped student and meta policy are the demo's learned methods.
        for method in ["imitation", "hrl", "pathfinding", "cbs", "swarm"] {
            let gif = std::fs::read(d.join(format!("demo/{case}/{method}.gif"))).unwrap();
            assert_eq!(&gif[..6], b"GIF89a", "{case} {method}");
        }
    }
    let Some(browser) = chromium() else { return };
    // The DOM after the page ran: ten pictures, each animated.
    let dom = headless(browser, d, &["--dump-dom"], &index);
    let dom = String::from_utf8_lossy(&dom.stdout);
    assert_eq!(dom.matches("<figure class=\"run\"").count(), 10, "{}", &dom[..dom.len().min(500)]);
    assert!(
        dom.matches("<animatetransform").count() + dom.matches("<animateTransform").count()
            >= 10 * 6
    );
    // The screenshot: the pictures are drawn (obstacles, agents), not a blank page.
    let shot = d.join("shot.png");
    let arg = format!("--screenshot={}", shot.display());
    headless(browser, d, &[&arg, "--window-size=1100,1400"], &index);
    let png = std::fs::read(&shot).expect("chromium wrote the screenshot");
    let decoder = png::Decoder::new(std::io::Cursor::new(png));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    let count = |rgb: [u8; 3]| buf.chunks_exact(channels).filter(|px| px[..3] == rgb).count();
    let pixels = (info.width * info.height) as usize;
    let obstacles = count([0x3a, 0x3a, 0x3a]);
    let free = count([0xf4, 0xf4, 0xf1]);
    assert!(obstacles > pixels / 100, "obstacles drawn: {obstacles} of {pixels} pixels");
    assert!(free > pixels / 20, "free cells drawn: {free} of {pixels} pixels");
    for (agent, rgb) in [(0, [0x1f, 0x6f, 0xd1]), (1, [0xe0, 0x54, 0x2a]), (2, [0x2a, 0x9d, 0x4b])]
    {
        assert!(count(rgb) > 50, "agent {agent} drawn");
    }
}
