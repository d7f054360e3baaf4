//! The figures a reader sees: the crowd animation shows its first frame in a static
//! viewer (rendered with `rsvg-convert` in the full tier) and draws the pedestrians'
//! Δ-contours one second ahead as its caption says; plan legends print rounded times;
//! a 3-D plan figure's sections follow the path's height.

use crate::common;
use riskplan_scene::Piece;
use serde_json::Value;
use std::path::Path;

/// The text of every `<text>` element of an SVG file (entities as written).
fn svg_texts(svg: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = svg;
    while let Some(i) = rest.find("<text") {
        rest = &rest[i..];
        let (Some(open), Some(close)) = (rest.find('>'), rest.find("</text>")) else { break };
        out.push(rest[open + 1..close].trim().to_string());
        rest = &rest[close..];
    }
    out
}

/// The crowd animation's frame groups (`<g …>` elements other than the transformed
/// corridor), each as (its opening tag, its contents).
fn crowd_frames(svg: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut rest = svg;
    while let Some(i) = rest.find("<g") {
        rest = &rest[i..];
        let open = rest.find('>').unwrap();
        let tag = rest[..=open].to_string();
        if tag.contains("transform=") {
            rest = &rest[open..];
            continue;
        }
        let close = rest.find("</g>").expect("a frame group ends");
        out.push((tag, rest[open + 1..close].to_string()));
        rest = &rest[close..];
    }
    out
}

/// The crowd animation's first frame, as a static viewer shows it: its group carries no
/// `visibility="hidden"` (only SMIL hides it later, `<set … to="hidden">`), every other
/// frame is hidden until its SMIL `<set>` shows it, and the first has pedestrians and
/// the robot.
fn assert_first_frame_static(svg: &str, what: &str) {
    let frames = crowd_frames(svg);
    assert!(frames.len() >= 2, "{what}: {} frame groups", frames.len());
    let (tag, body) = &frames[0];
    assert!(!tag.contains("visibility=\"hidden\""), "{what}: the first frame is hidden without SMIL: {tag}");
    assert!(body.contains("to=\"hidden\""), "{what}: the first frame is never hidden by the animation");
    assert!(body.matches("<circle").count() >= 3, "{what}: the first frame draws nothing");
    for (k, (tag, body)) in frames.iter().enumerate().skip(1) {
        assert!(tag.contains("visibility=\"hidden\""), "{what}: frame {k} is visible without SMIL: {tag}");
        assert!(body.contains("to=\"visible\""), "{what}: frame {k} is never shown");
    }
}

/// `svg` rendered to RGBA by `rsvg-convert`: `None` (skipped) when the program is missing
/// outside the full tier; in the full tier a missing program fails the test.
fn render(svg: &Path) -> Option<(u32, u32, Vec<u8>)> {
    let png = svg.with_extension("png");
    let run = std::process::Command::new("rsvg-convert").arg("-o").arg(&png).arg(svg).output();
    let out = match run {
        Ok(o) => o,
        Err(e) if !common::full_tier() => {
            eprintln!("skipped: rsvg-convert not found ({e}); scripts/setup-debian.sh installs librsvg2-bin");
            return None;
        }
        Err(e) => panic!("the full tier needs rsvg-convert (librsvg2-bin, scripts/setup-debian.sh): {e}"),
    };
    assert!(out.status.success(), "rsvg-convert {}: {}", svg.display(), String::from_utf8_lossy(&out.stderr));
    let decoder = png::Decoder::new(std::fs::File::open(&png).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.bit_depth, png::BitDepth::Eight, "rsvg-convert writes 8-bit PNGs");
    let rgba: Vec<u8> = match info.color_type {
        png::ColorType::Rgba => buf[..info.buffer_size()].to_vec(),
        png::ColorType::Rgb => buf[..info.buffer_size()].chunks(3).flat_map(|c| [c[0], c[1], c[2], 255]).collect(),
        other => panic!("unexpected PNG colour type {other:?}"),
    };
    Some((info.width, info.height, rgba))
}

/// In a static render of the crowd animation, pixels of the pedestrians' grey (#999) and
/// of the robot's blue (#1f5fbf at 80 % over the corridor) exist, at least the inside of
/// one disk of each (about 250 pixels; the antialiased text has a few dozen of that
/// grey): the first frame shows.
fn assert_first_frame_renders(svg: &Path) {
    let Some((w, h, rgba)) = render(svg) else { return };
    let px = |c: &[u8]| (c[0] as i32, c[1] as i32, c[2] as i32, c[3]);
    let grey = rgba
        .chunks(4)
        .map(px)
        .filter(|&(r, g, b, a)| a > 200 && [r, g, b].iter().all(|&v| (v - 153).abs() <= 1))
        .count();
    let blue = rgba.chunks(4).map(px).filter(|&(r, g, b, a)| a > 200 && b > 150 && b - r > 80 && b - g > 40).count();
    assert!(
        grey > 200,
        "{}: {w}×{h} render has {grey} pedestrian-grey pixels (the first frame is not drawn)",
        svg.display()
    );
    assert!(
        blue > 200,
        "{}: {w}×{h} render has {blue} robot-blue pixels (the first frame is not drawn)",
        svg.display()
    );
}

/// The committed `docs/figures/crowd.svg` shows its first frame in a static viewer.
#[test]
fn committed_crowd_figure_shows_its_first_frame() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/figures/crowd.svg");
    let svg = std::fs::read_to_string(&path).unwrap();
    assert_first_frame_static(&svg, "docs/figures/crowd.svg");
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("crowd.svg");
    std::fs::copy(&path, &copy).unwrap();
    assert_first_frame_renders(&copy);
}

/// `sim crowd --animate` against a running server writes an animation whose first frame
/// a static viewer shows, and whose dashed Δ-contours sit one second ahead of their
/// pedestrians (at the predicted centre: moved by the walking speed, 0.5–1.3 m/s, i.e.
/// 25–65 px at 50 px per metre), as the caption says.
#[cfg(feature = "service")]
#[test]
fn sim_crowd_animation_shows_its_first_frame_and_contours_ahead() {
    /// The value of attribute `name` in one opening tag.
    fn attr(tag: &str, name: &str) -> Option<f64> {
        let key = format!(" {name}=\"");
        let i = tag.find(&key)? + key.len();
        tag[i..].split('"').next()?.parse().ok()
    }
    let srv = common::server::serve(&[], &[], &["riskplan: ready"]);
    let dir = tempfile::tempdir().unwrap();
    let svg_path = dir.path().join("crowd.svg");
    let out = common::bin()
        .env("OPENBLAS_NUM_THREADS", "1")
        .args(["sim", "crowd", "--pedestrians", "6", "--episodes", "1", "--seed", "3", "--plan-time", "0.05"])
        .args(["--endpoint", &srv.endpoint])
        .arg("--animate")
        .arg(&svg_path)
        .output()
        .unwrap();
    assert!(out.status.success(), "sim crowd: {}", String::from_utf8_lossy(&out.stderr));
    let svg = std::fs::read_to_string(&svg_path).unwrap();
    assert_first_frame_static(&svg, "sim crowd --animate");
    let texts = svg_texts(&svg).join(" ");
    assert!(texts.contains("1 s ahead"), "the caption names the contours' time: {texts}");
    // the first frame's pedestrians: a grey disk, then its dashed contour
    let (_, body) = &crowd_frames(&svg)[0];
    let circles: Vec<&str> = body.split("<circle").skip(1).collect();
    let mut pairs = 0;
    for w in circles.windows(2) {
        if !(w[0].contains("fill=\"#999\"") && w[1].contains("stroke-dasharray")) {
            continue;
        }
        let (c, e) = (
            [attr(w[0], "cx").unwrap(), attr(w[0], "cy").unwrap()],
            [attr(w[1], "cx").unwrap(), attr(w[1], "cy").unwrap()],
        );
        let moved = (e[0] - c[0]).hypot(e[1] - c[1]);
        assert!(
            (20.0..=70.0).contains(&moved),
            "a contour {moved:.1} px from its pedestrian, not 1 s ahead: {} / {}",
            w[0],
            w[1]
        );
        pairs += 1;
    }
    assert!(pairs >= 6, "{pairs} pedestrians with their contour in the first frame");
    assert_first_frame_renders(&svg_path);
}

/// The significant digits of a printed decimal (`0.784` → 3, `1230` → 3, `0` → 1).
fn significant_digits(number: &str) -> usize {
    let digits: String = number.chars().filter(|c| c.is_ascii_digit()).collect();
    let s = digits.trim_start_matches('0').trim_end_matches('0');
    s.len().max(1)
}

fn plan_with_figure(scene: &str, dir: &Path) -> (Value, String) {
    let (plan, fig) = (dir.join(format!("{scene}.json")), dir.join(format!("{scene}.svg")));
    let out = common::bin()
        .env("OPENBLAS_NUM_THREADS", "1")
        .args(["plan", "--scene"])
        .arg(common::reference_dir().join(format!("{scene}.json")))
        .args(["--seed", "1", "--out"])
        .arg(&plan)
        .arg("--figure")
        .arg(&fig)
        .output()
        .unwrap();
    assert!(out.status.success(), "{scene}: {}", String::from_utf8_lossy(&out.stderr));
    (serde_json::from_str(&std::fs::read_to_string(plan).unwrap()).unwrap(), std::fs::read_to_string(fig).unwrap())
}

/// The numbers after `key` (`t=`, `x3=`) in a legend text, up to the next comma.
fn values_after(text: &str, key: &str) -> Vec<String> {
    text.match_indices(key)
        .filter(|(i, _)| *i == 0 || !text.as_bytes()[i - 1].is_ascii_alphanumeric())
        .map(|(i, _)| text[i + key.len()..].split([',', ' ']).next().unwrap_or("").to_string())
        .collect()
}

/// Plan legends print times with at most `viz::LEGEND_DIGITS` significant digits (the
/// piece times of a moving scene are arbitrary floats).
#[test]
fn plan_legend_times_are_rounded() {
    let dir = tempfile::tempdir().unwrap();
    for scene in ["example-c-delivery", "example-b-lane-change"] {
        let (_, svg) = plan_with_figure(scene, dir.path());
        let mut seen = 0;
        for text in svg_texts(&svg) {
            let mut numbers = values_after(&text, "t=");
            if let Some((_, list)) = text.split_once("at t = ").filter(|_| text.starts_with("waypoints")) {
                numbers.extend(list.split(", ").map(String::from));
            }
            for n in numbers {
                seen += 1;
                assert!(n.parse::<f64>().is_ok(), "{scene}: not a number: {n:?} in {text:?}");
                assert!(
                    significant_digits(&n) <= riskplan::viz::LEGEND_DIGITS,
                    "{scene}: the legend prints {n} ({} digits): {text:?}",
                    significant_digits(&n)
                );
            }
        }
        assert!(seen >= 4, "{scene}: {seen} times in the legend");
    }
}

/// The 3-D plan figure's contours are sections at the path's height: each legend entry
/// names its time and x3 level, the level is the path's x3 at that time, and the levels
/// change along the path (not one slice at x3 = 0 whatever the path does).
#[test]
fn plan_figure_3d_sections_follow_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let (plan, svg) = plan_with_figure("example-d2-cluttered-3d", dir.path());
    let pieces: Vec<Piece> = serde_json::from_value(plan["pieces"].clone()).unwrap();
    let x3 = |t: f64| -> f64 {
        let pc = pieces.iter().find(|p| t <= p.t1).unwrap_or(pieces.last().unwrap());
        pc.at(t.clamp(pc.t0, pc.t1))[2]
    };
    let texts = svg_texts(&svg);
    assert!(texts.iter().any(|t| t.contains("sections at the path")), "the title says what is sliced: {texts:?}");
    let mut levels = Vec::new();
    for text in texts.iter().filter(|t| t.starts_with("Cantelli contour")) {
        let (t, z) = (values_after(text, "t="), values_after(text, "x3="));
        assert!(t.len() == 1 && z.len() == 1, "a contour's legend names its time and its x3 level: {text:?}");
        let (t, z): (f64, f64) = (t[0].parse().unwrap(), z[0].parse().unwrap());
        // both printed to 3 significant digits: the path moves less than 0.01 in the time's rounding
        assert!((x3(t) - z).abs() <= 0.01, "{text:?}: the path is at x3 = {} at t = {t}", x3(t));
        levels.push(z);
    }
    assert!(levels.len() >= 3, "{} sections: {texts:?}", levels.len());
    let spread =
        levels.iter().copied().fold(f64::NEG_INFINITY, f64::max) - levels.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(spread > 0.5, "the sections stay at one height ({levels:?}) while the path climbs from -1 to 1");
}
