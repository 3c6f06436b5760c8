//! The study report's blocks (headings, paragraphs, tables, figures) as markdown and as a
//! self-contained HTML page.

use std::fmt::Write as _;

/// A part of the report, rendered as markdown and as HTML.
pub enum Block {
    Heading(String),
    Para(String),
    Table(Vec<String>, Vec<Vec<String>>),
    Image(String, String),
}

fn escape(t: &str) -> String {
    t.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Inline markdown of the report's text (only `code` and **bold**) as HTML.
fn inline_html(t: &str) -> String {
    let mut out = String::new();
    for (i, part) in escape(t).split('`').enumerate() {
        if i % 2 == 1 {
            let _ = write!(out, "<code>{part}</code>");
        } else {
            for (j, p) in part.split("**").enumerate() {
                if j % 2 == 1 {
                    let _ = write!(out, "<b>{p}</b>");
                } else {
                    out.push_str(p);
                }
            }
        }
    }
    out
}

pub fn render(blocks: &[Block], title: &str) -> (String, String) {
    let mut md = format!("# {title}\n\n");
    let mut html = format!(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{0}</title>\n<style>body{{font-family:sans-serif;max-width:70em;margin:auto}}table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}}img{{max-width:100%}}</style></head><body>\n<h1>{0}</h1>\n",
        escape(title)
    );
    for b in blocks {
        match b {
            Block::Heading(t) => {
                let _ = writeln!(md, "## {t}\n");
                let _ = writeln!(html, "<h2>{}</h2>", inline_html(t));
            }
            Block::Para(t) => {
                let _ = writeln!(md, "{t}\n");
                let _ = writeln!(html, "<p>{}</p>", inline_html(t));
            }
            Block::Table(header, rows) => {
                let _ = writeln!(md, "| {} |", header.join(" | "));
                let _ = writeln!(md, "|{}", "---|".repeat(header.len()));
                html.push_str("<table><tr>");
                for h in header {
                    let _ = write!(html, "<th>{}</th>", inline_html(h));
                }
                html.push_str("</tr>\n");
                for r in rows {
                    let _ = writeln!(md, "| {} |", r.join(" | "));
                    html.push_str("<tr>");
                    for c in r {
                        let _ = write!(html, "<td>{}</td>", inline_html(c));
                    }
                    html.push_str("</tr>\n");
                }
                md.push('\n');
                html.push_str("</table>\n");
            }
            Block::Image(path, caption) => {
                let _ = writeln!(md, "![{path}]({path})\n\n*{caption}*\n");
                let _ = writeln!(
                    html,
                    "<figure><img src=\"{}\" alt=\"\"><figcaption>{}</figcaption></figure>",
                    escape(path),
                    inline_html(caption)
                );
            }
        }
    }
    html.push_str("</body></html>\n");
    (md, html)
}
