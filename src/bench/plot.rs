//! Log-log line plots (SVG, plotters) for the benchmarks.

use plotters::prelude::*;
use std::path::Path;

pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    /// Mark these points as the Pareto front (a wide grey band under the series' lines).
    pub pareto: bool,
}

/// The line of series `k`: its colour, or for the Pareto front a wide translucent grey band
/// (drawn in a colour of its own it took the blue of the first series, which it mostly
/// follows, and hid it).
fn line_style(k: usize, series: &Series) -> ShapeStyle {
    if series.pareto {
        BLACK.mix(0.2).stroke_width(9)
    } else {
        COLORS[k % COLORS.len()].stroke_width(2)
    }
}

const COLORS: [RGBColor; 12] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
    RGBColor(0, 0, 0),
    RGBColor(255, 187, 120),
];

/// A log axis's tick to three figures: `1e-4`, `0.003`, `1000`.
fn tick_label(v: f64) -> String {
    crate::io::significant(v, 3)
}

/// Width of the picture's legend column, right of the plot: a legend inside the plot hid the
/// points under it.
const LEGEND_WIDTH: u32 = 220;

/// A line of each series' colour and its name, one below the other, in `area`.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    series: &[Series],
) -> anyhow::Result<()> {
    for (k, s) in series.iter().enumerate() {
        let y = 60 + 22 * k as i32;
        let line = PathElement::new(vec![(8, y), (34, y)], line_style(k, s));
        area.draw(&line).map_err(|e| anyhow::anyhow!("{e}"))?;
        let name = Text::new(s.name.clone(), (42, y - 7), ("sans-serif", 14));
        area.draw(&name).map_err(|e| anyhow::anyhow!("{e}"))?;
    }
    Ok(())
}

/// Least and greatest value a logarithmic axis shows: plotters walks an axis's powers of ten
/// from its lower end by multiplication, which never ends from a subnormal lower end (it stays
/// 0) or towards an upper end past `f64::MAX` (a run's metric of 1e308, a range widened by half,
/// is infinite). 600 decades: any figure a run means.
const AXIS_RANGE: (f64, f64) = (1e-300, 1e300);

/// Whether a point can stand on logarithmic axes ([`AXIS_RANGE`]).
fn plottable((x, y): &(f64, f64)) -> bool {
    let within = |v: f64| (AXIS_RANGE.0..=AXIS_RANGE.1).contains(&v);
    within(*x) && within(*y)
}

/// Writes an SVG plot with logarithmic axes; values that are not positive, or lie beyond
/// [`AXIS_RANGE`], are dropped. Drawn in memory
/// and written whole ([`super::write_named`]); an error names the file.
pub fn log_log_plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> anyhow::Result<()> {
    use anyhow::Context;
    let mut svg = String::new();
    draw_log_log(&mut svg, (title, x_label, y_label), series)
        .with_context(|| format!("cannot draw {}", path.display()))?;
    super::write_named(path, svg)
}

/// [`log_log_plot`]'s drawing, into `svg`.
fn draw_log_log(
    svg: &mut String,
    (title, x_label, y_label): (&str, &str, &str),
    series: &[Series],
) -> anyhow::Result<()> {
    let all: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.points.iter().copied())
        .filter(plottable)
        .collect();
    let (mut x0, mut x1, mut y0, mut y1) = all.iter().fold(
        (f64::MAX, f64::MIN, f64::MAX, f64::MIN),
        |(a, b, c, d), (x, y)| (a.min(*x), b.max(*x), c.min(*y), d.max(*y)),
    );
    if all.is_empty() {
        (x0, x1, y0, y1) = (1.0, 10.0, 1.0, 10.0);
    }
    let (x0, x1, y0, y1) = (x0 / 1.5, x1 * 1.5, y0 / 1.5, y1 * 1.5);
    let root = SVGBackend::with_string(svg, (900 + LEGEND_WIDTH, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e}"))?;
    let (plot, legend) = root.split_horizontally(900);
    let mut chart = ChartBuilder::on(&plot)
        .caption(title, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .x_label_formatter(&|v| tick_label(*v))
        .y_label_formatter(&|v| tick_label(*v))
        .draw()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    // The Pareto front first, so that its band lies under the lines it follows.
    let mut order: Vec<(usize, &Series)> = series.iter().enumerate().collect();
    order.sort_by_key(|(_, s)| !s.pareto);
    for (k, s) in order {
        let color = COLORS[k % COLORS.len()];
        let pts: Vec<(f64, f64)> = s.points.iter().copied().filter(plottable).collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), line_style(k, s)))
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        // The front's points are other series' points: marked by them.
        if !s.pareto {
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 4, color.filled())))
                .map_err(|e| anyhow::anyhow!("{e}"))?;
        }
    }
    draw_legend(&legend, series)?;
    root.present().map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Figures at the ends of `f64` (a metric of 1e308, a subnormal wall time) are left out and
    /// the plot drawn: with them in, plotters' walk over the axis's powers of ten never ended.
    #[test]
    fn extreme_values_are_left_out_of_the_axes() {
        for extreme in [1e308, 8e307, 1e-308, 5e-324, f64::MAX] {
            let series = [Series {
                name: "run".into(),
                points: vec![(1.0, extreme), (2.0, 1.0), (extreme, 3.0)],
                pareto: false,
            }];
            let mut svg = String::new();
            draw_log_log(&mut svg, ("t", "x", "y"), &series).unwrap();
            assert!(svg.contains("<svg"), "{extreme}");
        }
        assert!(plottable(&(1e-300, 1e300)) && !plottable(&(1e-301, 1.0)));
        assert!(!plottable(&(1.0, f64::NAN)) && !plottable(&(0.0, 1.0)));
    }
}
