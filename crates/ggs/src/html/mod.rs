//! Self-contained HTML pages: the registration report ([`registration`]) and the pieces the
//! benchmark report shares with it (page shell, escaping, tables, SVG charts).
//!
//! Every page is one file that needs nothing at view time: pictures are inline PNG `data:`
//! URLs or inline SVG, style and script are inline, and nothing names a network address, so
//! a report opens the same from a laptop, a cluster's scratch disk or an e-mail attachment.

pub mod alignment;
pub mod registration;

use std::fmt::Write;

/// `s` with `& < > " '` escaped for HTML text and attribute values.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(c),
        }
    }
    out
}

const STYLE: &str = r#"
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0;color:#1d232b;background:#f6f7f9}
main{max-width:1180px;margin:0 auto;padding:18px 22px 60px}
h1{font-size:22px;margin:8px 0 4px}h2{font-size:17px;margin:28px 0 8px;border-bottom:1px solid #d8dce2;padding-bottom:4px}
.sub{color:#5b6673}.banner{padding:10px 14px;border-radius:6px;margin:12px 0;font-weight:600}
.ok{background:#e3f4e6;color:#1e5b2a}.warn{background:#fff1d6;color:#7a4b00}.bad{background:#fde2e1;color:#8a1f17}
table{border-collapse:collapse;background:#fff;font-variant-numeric:tabular-nums}
th,td{border:1px solid #dde1e6;padding:3px 8px;text-align:right}th{background:#eef1f4;position:sticky;top:0}
td.l,th.l{text-align:left}tr.chosen td{background:#e9f3ff;font-weight:600}tr.fail td{background:#fff4f3}
table.sortable th{cursor:pointer;user-select:none}table.sortable th:hover{background:#dfe5ec}
.views{display:grid;grid-template-columns:repeat(3,1fr);gap:10px}.views figure{margin:0;background:#fff;border:1px solid #dde1e6}
.views img{width:100%;display:block}figcaption{font-size:12px;color:#5b6673;padding:3px 6px}
.legend i{display:inline-block;width:11px;height:11px;border-radius:2px;margin:0 4px 0 12px;vertical-align:-1px}
details{margin:2px 0}summary{cursor:pointer}details p{margin:4px 0 8px 16px;color:#3b4550;max-width:760px}
pre{background:#fff;border:1px solid #dde1e6;padding:8px;overflow-x:auto}
.gallery{display:grid;grid-template-columns:repeat(auto-fill,minmax(340px,1fr));gap:12px}
.gallery figure{margin:0;background:#fff;border:1px solid #dde1e6}.gallery img{width:100%;display:block}
canvas{background:#fff;border:1px solid #dde1e6;touch-action:none;max-width:100%}
.scroll{max-height:620px;overflow:auto;border:1px solid #dde1e6}
"#;

/// Sorts a `table.sortable` by the clicked column: numbers numerically (cells that are not
/// numbers last), text alphabetically; a second click reverses.
pub const SORT_SCRIPT: &str = r#"
document.querySelectorAll('table.sortable').forEach(function (table) {
  table.querySelectorAll('th').forEach(function (th, col) {
    th.addEventListener('click', function () {
      var body = table.tBodies[0], rows = Array.prototype.slice.call(body.rows);
      var dir = th.dataset.dir === 'asc' ? -1 : 1; th.dataset.dir = dir === 1 ? 'asc' : 'desc';
      var key = function (r) { var c = r.cells[col]; return c.dataset.v !== undefined ? c.dataset.v : c.textContent; };
      rows.sort(function (a, b) {
        var x = key(a), y = key(b), nx = parseFloat(x), ny = parseFloat(y);
        var fx = isFinite(nx), fy = isFinite(ny);
        if (fx && fy) return dir * (nx - ny);
        if (fx !== fy) return fx ? -1 : 1;
        return dir * String(x).localeCompare(String(y));
      });
      rows.forEach(function (r) { body.appendChild(r); });
    });
  });
});
"#;

/// A complete page: `title`, the body HTML and inline scripts run after the body.
pub fn page(title: &str, body: &str, scripts: &[&str]) -> String {
    let mut s = String::with_capacity(body.len() + 4096);
    let _ = write!(
        s,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width,initial-scale=1\">\
         <title>{}</title><style>{STYLE}</style></head><body><main>\n{body}\n</main>",
        escape(title)
    );
    for script in scripts {
        let _ = write!(s, "<script>{script}</script>");
    }
    s.push_str("</body></html>\n");
    s
}

/// The "Settings" section: every key of a settings object and its value, folded.
pub fn settings_table(settings: &serde_json::Value) -> String {
    let serde_json::Value::Object(fields) = settings else {
        return String::new();
    };
    let mut s = String::from(
        "<h2>Settings</h2><details><summary>every setting in force (docs/settings.md)</summary>\
         <table><thead><tr><th>key</th><th>value</th></tr></thead><tbody>",
    );
    for (key, value) in fields {
        let shown = match value {
            serde_json::Value::Null => "unset".to_string(),
            serde_json::Value::String(text) => text.clone(),
            other => other.to_string(),
        };
        let _ = write!(
            s,
            "<tr><td><code>{}</code></td><td>{}</td></tr>",
            escape(key),
            escape(&shown)
        );
    }
    s + "</tbody></table></details>"
}

/// A number for a table cell: `digits` decimals, "–" for NaN or infinity.
pub fn num(v: f64, digits: usize) -> String {
    if v.is_finite() {
        format!("{v:.digits$}")
    } else {
        "–".to_string()
    }
}

/// A term with its definition one click away (`<details>`).
pub fn definition(term: &str, value: &str, meaning: &str) -> String {
    format!(
        "<details><summary><b>{}</b>: {}</summary><p>{}</p></details>\n",
        escape(term),
        value,
        escape(meaning)
    )
}

/// The colour key of the pictures: target blue, source orange.
pub fn legend() -> String {
    let [tr, tg, tb] = crate::render::TARGET_COLOR;
    let [sr, sg, sb] = crate::render::SOURCE_COLOR;
    format!(
        "<p class=\"legend\"><i style=\"background:rgb({tr},{tg},{tb})\"></i>target\
         <i style=\"background:rgb({sr},{sg},{sb})\"></i>source \
         <span class=\"sub\">(nearer points are brighter)</span></p>"
    )
}

/// Horizontal bars, one per `(label, value)`, labelled with the value and `unit`.
pub fn bar_chart_svg(items: &[(String, f64)], unit: &str) -> String {
    let max = items.iter().map(|i| i.1).fold(0.0f64, f64::max);
    let (w, row, label_w) = (620.0, 24.0, 190.0);
    let h = row * items.len() as f64 + 8.0;
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" font-family=\"sans-serif\" font-size=\"12\">"
    );
    for (k, (label, v)) in items.iter().enumerate() {
        let y = 4.0 + row * k as f64;
        let len = if max > 0.0 {
            (w - label_w - 90.0) * v / max
        } else {
            0.0
        };
        let _ = write!(
            s,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"end\">{}</text>\
             <rect x=\"{label_w}\" y=\"{}\" width=\"{len:.1}\" height=\"{}\" fill=\"#4f7fbf\"/>\
             <text x=\"{:.1}\" y=\"{}\">{} {unit}</text>",
            label_w - 6.0,
            y + 15.0,
            escape(label),
            y + 3.0,
            row - 8.0,
            label_w + len + 5.0,
            y + 15.0,
            num(*v, 1)
        );
    }
    s.push_str("</svg>");
    s
}

/// A histogram of `values` over logarithmic bins from `lo` to `hi` (values outside are
/// counted in the first or last bin), with a dashed line at `threshold`.
pub fn log_histogram_svg(title: &str, values: &[f64], lo: f64, hi: f64, threshold: f64) -> String {
    const BINS: usize = 24;
    let (l0, l1) = (lo.log10(), hi.log10());
    let mut counts = [0usize; BINS];
    for v in values.iter().filter(|v| v.is_finite()) {
        let t = ((v.max(lo).log10() - l0) / (l1 - l0) * BINS as f64).floor();
        counts[(t.max(0.0) as usize).min(BINS - 1)] += 1;
    }
    let max = counts.iter().copied().max().unwrap_or(0).max(1) as f64;
    let (w, h, left, bottom) = (440.0, 200.0, 36.0, 34.0);
    let (pw, ph) = (w - left - 24.0, h - bottom - 24.0);
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" font-family=\"sans-serif\" font-size=\"11\">\
         <text x=\"{left}\" y=\"14\" font-size=\"13\">{}</text>",
        escape(title)
    );
    let bw = pw / BINS as f64;
    for (k, &c) in counts.iter().enumerate() {
        let bh = ph * c as f64 / max;
        let _ = write!(
            s,
            "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"{:.1}\" height=\"{bh:.1}\" fill=\"#4f7fbf\"><title>{c}</title></rect>",
            left + bw * k as f64 + 0.5,
            24.0 + ph - bh,
            bw - 1.0
        );
    }
    let x_of = |v: f64| left + pw * (v.log10() - l0) / (l1 - l0);
    let mut tick = 10f64.powf(l0.ceil());
    while tick <= hi * 1.0001 {
        let _ = write!(
            s,
            "<text x=\"{:.1}\" y=\"{}\" text-anchor=\"middle\">{}</text>",
            x_of(tick),
            h - bottom + 14.0,
            trim_number(tick)
        );
        tick *= 10.0;
    }
    if threshold > lo && threshold < hi {
        let x = x_of(threshold);
        let _ = write!(
            s,
            "<line x1=\"{x:.1}\" x2=\"{x:.1}\" y1=\"22\" y2=\"{:.1}\" stroke=\"#c0392b\" stroke-dasharray=\"4 3\"/>\
             <text x=\"{:.1}\" y=\"{}\" fill=\"#c0392b\">threshold {}</text>",
            24.0 + ph,
            x + 3.0,
            h - 6.0,
            trim_number(threshold)
        );
    }
    let _ = write!(
        s,
        "<text x=\"10\" y=\"{:.1}\" transform=\"rotate(-90 10 {:.1})\" text-anchor=\"middle\">pairs (max {})</text></svg>",
        24.0 + ph / 2.0,
        24.0 + ph / 2.0,
        max as usize
    );
    s
}

/// `v` in at most 4 significant digits, without trailing zeros.
pub fn trim_number(v: f64) -> String {
    let s = format!("{:.4}", v);
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s.is_empty() || s == "-" {
        "0".into()
    } else {
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escape_covers_markup_and_quotes() {
        assert_eq!(
            escape("<a href=\"x\">'&'</a>"),
            "&lt;a href=&quot;x&quot;&gt;&#39;&amp;&#39;&lt;/a&gt;"
        );
    }

    #[test]
    fn a_page_names_no_network_address() {
        let body = bar_chart_svg(&[("search".into(), 12.0), ("verify".into(), 3.5)], "ms")
            + &log_histogram_svg("RRE", &[0.1, 1.0, 50.0, f64::NAN], 0.01, 180.0, 15.0);
        let html = page("t", &body, &[SORT_SCRIPT]);
        let without_svg_namespace = html.replace("http://www.w3.org/2000/svg", "");
        assert!(!without_svg_namespace.contains("http"), "{html}");
        assert!(html.contains("threshold 15"));
        assert!(html.starts_with("<!DOCTYPE html>") && html.ends_with("</html>\n"));
    }

    #[test]
    fn histogram_counts_every_finite_value_once() {
        let values = [0.001, 0.02, 0.5, 0.5, 7.0, 179.0, 1e9];
        let svg = log_histogram_svg("x", &values, 0.01, 180.0, 5.0);
        let total: usize = svg
            .match_indices("<title>")
            .map(|(i, _)| {
                let rest = &svg[i + 7..];
                rest[..rest.find('<').unwrap()].parse::<usize>().unwrap()
            })
            .sum();
        assert_eq!(total, values.len());
    }

    #[test]
    fn numbers_print_plainly() {
        assert_eq!(num(f64::NAN, 2), "–");
        assert_eq!(num(1.23456, 2), "1.23");
        assert_eq!(trim_number(0.05), "0.05");
        assert_eq!(trim_number(100.0), "100");
        assert_eq!(trim_number(0.0), "0");
    }
}
