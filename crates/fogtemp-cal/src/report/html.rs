//! A self-contained `report.html` beside every `report.md`: the same text and tables, and
//! every figure the Markdown links (`![alt](figure.svg)`) inlined as SVG, so the page needs
//! no other file and loads nothing from the network.
//!
//! The converter covers the Markdown the reports write, no more: `#` headings, pipe
//! tables, `- ` lists, paragraphs, figures on a line of their own, and inline `code`,
//! `**bold**` and `[text](link)` (links to a sibling `.md` report point to its `.html`).

use std::path::Path;

use crate::error::CalError;
use crate::output::write_file_atomic;

/// Page style: readable width, ruled tables, figures scaled to the page.
const STYLE: &str = "body{font-family:sans-serif;max-width:1200px;margin:1em auto;padding:0 1em;color:#222;line-height:1.4}\
table{border-collapse:collapse;margin:0.6em 0;display:block;max-width:100%;overflow-x:auto}td code{white-space:nowrap}th,td{border:1px solid #bbb;padding:0.2em 0.6em;text-align:left}\
th{background:#eee}td{font-variant-numeric:tabular-nums;vertical-align:top}td.prose{min-width:28em}code{background:#f3f3f3;padding:0 0.2em}\
pre{background:#f3f3f3;padding:0.5em;overflow-x:auto}figure{margin:1em 0}figure svg{max-width:100%;height:auto;display:block}figcaption{color:#555;font-size:0.9em}";

/// HTML-escapes text (`&`, `<`, `>`, `"`).
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            _ => out.push(c),
        }
    }
    out
}

/// A link target in the HTML page: a sibling Markdown report becomes its HTML page.
fn html_target(href: &str) -> String {
    match href.strip_suffix(".md") {
        Some(stem) if !href.contains("://") => format!("{stem}.html"),
        _ => href.to_string(),
    }
}

/// Inline Markdown (`code`, `**bold**`, `[text](link)`) to HTML, the rest escaped.
pub fn inline(text: &str) -> String {
    let mut out = String::new();
    let mut rest = text;
    while let Some(c) = rest.chars().next() {
        if c == '`' {
            if let Some(end) = rest[1..].find('`') {
                out.push_str(&format!("<code>{}</code>", escape(&rest[1..=end])));
                rest = &rest[end + 2..];
                continue;
            }
        }
        if let Some(after) = rest.strip_prefix("**") {
            if let Some(end) = after.find("**") {
                out.push_str(&format!("<strong>{}</strong>", inline(&after[..end])));
                rest = &after[end + 2..];
                continue;
            }
        }
        if c == '[' {
            if let Some((label, href, len)) = link(rest) {
                out.push_str(&format!("<a href=\"{}\">{}</a>", escape(&html_target(href)), inline(label)));
                rest = &rest[len..];
                continue;
            }
        }
        out.push_str(&escape(&rest[..c.len_utf8()]));
        rest = &rest[c.len_utf8()..];
    }
    out
}

/// `[label](href)` at the start of `text`: the label, the target and the length consumed.
fn link(text: &str) -> Option<(&str, &str, usize)> {
    let close = text.find("](")?;
    let end = text[close + 2..].find(')')? + close + 2;
    Some((&text[1..close], &text[close + 2..end], end + 1))
}

/// `![alt](file)` when that is the whole (trimmed) line.
fn figure_line(line: &str) -> Option<(&str, &str)> {
    let (label, href, len) = link(line.trim().strip_prefix('!')?)?;
    (len == line.trim().len() - 1).then_some((label, href))
}

/// The cells of a pipe-table row; `\|` is a pipe inside a cell.
fn cells(line: &str) -> Vec<String> {
    let inner = line.trim().strip_prefix('|').unwrap_or(line.trim());
    let inner =
        if inner.ends_with('|') && !inner.ends_with("\\|") { &inner[..inner.len() - 1] } else { inner };
    let mut out = Vec::new();
    let mut cell = String::new();
    let mut chars = inner.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\\' if chars.peek() == Some(&'|') => {
                chars.next();
                cell.push('|');
            }
            '|' => out.push(std::mem::take(&mut cell)),
            _ => cell.push(c),
        }
    }
    out.push(cell);
    out.iter().map(|c| c.trim().to_string()).collect()
}

fn is_separator(line: &str) -> bool {
    let line = line.trim();
    line.starts_with('|') && line.chars().all(|c| matches!(c, '|' | '-' | ':' | ' '))
}

/// An SVG document made fit to sit inside HTML: without its XML prolog and namespace
/// declarations (an inline `<svg>` needs neither) and with a `viewBox` so it scales.
pub fn inline_svg(svg: &str) -> String {
    let body = match svg.find("<svg") {
        Some(start) => &svg[start..],
        None => svg,
    };
    let Some(tag_end) = body.find('>') else { return body.to_string() };
    let mut tag = body[..tag_end].to_string();
    for ns in [" xmlns=\"http://www.w3.org/2000/svg\"", " xmlns:xlink=\"http://www.w3.org/1999/xlink\""] {
        tag = tag.replace(ns, "");
    }
    if !tag.contains("viewBox") {
        let attr = |name: &str| {
            let key = format!(" {name}=\"");
            let start = tag.find(&key)? + key.len();
            let len = tag[start..].find('"')?;
            tag[start..start + len].parse::<f64>().ok()
        };
        if let (Some(w), Some(h)) = (attr("width"), attr("height")) {
            tag.push_str(&format!(" viewBox=\"0 0 {w} {h}\""));
        }
    }
    format!("{tag}{}", &body[tag_end..])
}

/// Converts a report's Markdown to a self-contained HTML page titled `title`; each figure
/// line's file is handed to `figure` for its SVG text.
///
/// # Errors
/// What `figure` returns for a figure it cannot supply.
pub fn markdown_to_html(
    markdown: &str,
    title: &str,
    mut figure: impl FnMut(&str) -> Result<String, CalError>,
) -> Result<String, CalError> {
    let mut html = format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n",
        escape(title)
    );
    let lines: Vec<&str> = markdown.lines().collect();
    let mut i = 0;
    // A paragraph's lines, each with whether it ends in a Markdown hard break (two spaces:
    // the diagnose verdict's lines, which ran together in one paragraph, review14 F13).
    let mut paragraph: Vec<(&str, bool)> = Vec::new();
    let flush = |paragraph: &mut Vec<(&str, bool)>, html: &mut String| {
        if !paragraph.is_empty() {
            // Joined first, so a bold or code span may run across lines; a hard break is a
            // character no report writes, replaced once the text is HTML.
            const HARD_BREAK: char = '\u{1}';
            let mut text = String::new();
            for (k, (line, _)) in paragraph.iter().enumerate() {
                if k > 0 {
                    text.push(if paragraph[k - 1].1 { HARD_BREAK } else { ' ' });
                }
                text.push_str(line);
            }
            let body = inline(&text).replace(HARD_BREAK, "<br>\n");
            html.push_str(&format!("<p>{body}</p>\n"));
            paragraph.clear();
        }
    };
    while let Some(&line) = lines.get(i) {
        let trimmed = line.trim();
        let level = trimmed.chars().take_while(|&c| c == '#').count();
        if trimmed.is_empty() {
            flush(&mut paragraph, &mut html);
        } else if trimmed.starts_with("```") {
            // A fenced block (a text table): kept as written, up to the closing fence.
            flush(&mut paragraph, &mut html);
            let start = i + 1;
            i = start;
            while lines.get(i).is_some_and(|l| !l.trim().starts_with("```")) {
                i += 1;
            }
            let body: Vec<String> =
                lines.get(start..i).unwrap_or_default().iter().map(|l| escape(l)).collect();
            html.push_str(&format!("<pre>{}</pre>\n", body.join("\n")));
        } else if (1..=6).contains(&level) && trimmed[level..].starts_with(' ') {
            flush(&mut paragraph, &mut html);
            html.push_str(&format!("<h{level}>{}</h{level}>\n", inline(trimmed[level..].trim())));
        } else if let Some((alt, file)) = figure_line(trimmed) {
            flush(&mut paragraph, &mut html);
            html.push_str(&format!(
                "<figure>\n{}\n<figcaption>{}</figcaption>\n</figure>\n",
                inline_svg(&figure(file)?),
                inline(alt)
            ));
        } else if trimmed.starts_with('|') {
            flush(&mut paragraph, &mut html);
            let start = i;
            while lines.get(i).is_some_and(|l| l.trim().starts_with('|')) {
                i += 1;
            }
            html.push_str(&table(&lines[start..i]));
            continue;
        } else if let Some(item) = trimmed.strip_prefix("- ") {
            flush(&mut paragraph, &mut html);
            html.push_str("<ul>\n");
            html.push_str(&format!("<li>{}</li>\n", inline(item)));
            while let Some(next) = lines.get(i + 1).and_then(|l| l.trim().strip_prefix("- ")) {
                html.push_str(&format!("<li>{}</li>\n", inline(next)));
                i += 1;
            }
            html.push_str("</ul>\n");
        } else {
            paragraph.push((trimmed, line.ends_with("  ")));
        }
        i += 1;
    }
    flush(&mut paragraph, &mut html);
    html.push_str("</body>\n</html>\n");
    Ok(html)
}

/// Cells longer than this are prose (a note, a statement): they get a readable width
/// instead of being squeezed into a narrow column many lines tall beside the numbers.
const PROSE_CELL_CHARS: usize = 60;

/// A pipe table (header, separator, rows) as an HTML table.
fn table(lines: &[&str]) -> String {
    let mut html = String::from("<table>\n");
    let has_header = lines.get(1).is_some_and(|l| is_separator(l));
    for (k, line) in lines.iter().enumerate() {
        if is_separator(line) {
            continue;
        }
        let tag = if has_header && k == 0 { "th" } else { "td" };
        html.push_str("<tr>");
        for cell in cells(line) {
            let class =
                if tag == "td" && cell.chars().count() > PROSE_CELL_CHARS { " class=\"prose\"" } else { "" };
            html.push_str(&format!("<{tag}{class}>{}</{tag}>", inline(&cell)));
        }
        html.push_str("</tr>\n");
    }
    html.push_str("</table>\n");
    html
}

/// Writes the HTML page of the Markdown report `md_path` beside it (`report.md` ->
/// `report.html`), reading each figure from the report's folder.
///
/// # Errors
/// [`CalError::Io`] naming the Markdown file or a figure that cannot be read, or the page
/// that cannot be written.
pub fn write_html_beside(md_path: &Path) -> Result<(), CalError> {
    let read = |path: &Path| {
        crate::output::read_current(path).map_err(|source| CalError::Io { path: path.to_path_buf(), source })
    };
    let markdown = read(md_path)?;
    let dir = md_path.parent().unwrap_or_else(|| Path::new("."));
    let title =
        markdown.lines().find_map(|l| l.strip_prefix("# ")).unwrap_or("fogtemp report").replace('`', "");
    let html = markdown_to_html(&markdown, &title, |file| read(&dir.join(file)))?;
    write_file_atomic(&md_path.with_extension("html"), |w| w.write_all(html.as_bytes()))
}

#[cfg(test)]
mod tests {
    use super::*;

    const SVG: &str = "<?xml version=\"1.0\"?>\n<svg width=\"300\" height=\"200\" xmlns=\"http://www.w3.org/2000/svg\"><text>a&lt;b</text></svg>";

    #[test]
    fn fenced_blocks_keep_their_lines_and_spacing() {
        let md = "Table:\n\n```text\n  method   CV\n  poly     0.1 <- chosen\n```\nafter\n";
        let html = markdown_to_html(md, "t", |_| Ok(String::new())).unwrap();
        assert!(html.contains("<pre>  method   CV\n  poly     0.1 &lt;- chosen</pre>"), "{html}");
        assert!(html.contains("<p>after</p>") && !html.contains("```"), "{html}");
    }

    #[test]
    fn a_hard_break_ends_a_line_and_plain_lines_join() {
        // The diagnose verdict: lines ending in two spaces, the rest of a paragraph joined.
        let md = "**Verdict:** the simulation leaves out a.  \nThese runs hardly tell a from b.  \nThe rest\nof it.\n";
        let html = markdown_to_html(md, "t", |_| Ok(String::new())).unwrap();
        assert!(
            html.contains(
                "<p><strong>Verdict:</strong> the simulation leaves out a.<br>\nThese runs hardly tell a from b.<br>\nThe rest of it.</p>"
            ),
            "{html}"
        );
    }

    #[test]
    fn tables_headings_lists_and_inline_markup_convert() {
        let md = "# Fit of `m.fogm`\n\nSome **bold** and a [link](poly/report.md).\n\n\
                  | run | raw |\n|---|---|\n| a<b | **0.1** |\n\n- one\n- two\n";
        let html = markdown_to_html(md, "t", |_| Ok(String::new())).unwrap();
        assert!(html.contains("<h1>Fit of <code>m.fogm</code></h1>"));
        assert!(
            html.contains("<p>Some <strong>bold</strong> and a <a href=\"poly/report.html\">link</a>.</p>")
        );
        assert!(html.contains("<tr><th>run</th><th>raw</th></tr>"));
        assert!(html.contains("<tr><td>a&lt;b</td><td><strong>0.1</strong></td></tr>"));
        assert!(html.contains("<ul>\n<li>one</li>\n<li>two</li>\n</ul>"));
        assert!(!html.contains("|---|"));
    }

    #[test]
    fn long_cells_are_marked_as_prose() {
        let note = "x".repeat(PROSE_CELL_CHARS + 1);
        let short = "y".repeat(PROSE_CELL_CHARS);
        let md = format!("| effect | note |\n|---|---|\n| {short} | {note} |\n");
        let html = markdown_to_html(&md, "t", |_| Ok(String::new())).unwrap();
        assert!(
            html.contains(&format!("<tr><td>{short}</td><td class=\"prose\">{note}</td></tr>")),
            "{html}"
        );
    }

    #[test]
    fn an_escaped_pipe_stays_inside_its_cell() {
        let md = "| model | what |\n|---|---|\n| `m` | all while \\|dT/dt\\| >= 0.05 |\n";
        let html = markdown_to_html(md, "t", |_| Ok(String::new())).unwrap();
        assert!(
            html.contains("<tr><td><code>m</code></td><td>all while |dT/dt| &gt;= 0.05</td></tr>"),
            "{html}"
        );
    }

    #[test]
    fn figures_are_inlined_without_namespace_and_with_a_view_box() {
        let md = "## Axis 0\n\n![runs](runs.svg)\n\n![allan](allan.svg)\n";
        let mut asked = Vec::new();
        let html = markdown_to_html(md, "t", |f| {
            asked.push(f.to_string());
            Ok(SVG.to_string())
        })
        .unwrap();
        assert_eq!(asked, ["runs.svg", "allan.svg"]);
        assert_eq!(html.matches("<svg width=\"300\" height=\"200\" viewBox=\"0 0 300 200\">").count(), 2);
        assert!(!html.contains("http"), "{html}");
        assert!(!html.contains("src="));
        assert!(!html.contains("<?xml"));
        assert!(html.contains("<figcaption>runs</figcaption>"));
    }

    #[test]
    fn a_missing_figure_is_an_error() {
        let err = markdown_to_html("![runs](runs.svg)\n", "t", |f| {
            Err(CalError::Io { path: f.into(), source: std::io::Error::other("gone") })
        });
        assert!(err.is_err());
    }
}
