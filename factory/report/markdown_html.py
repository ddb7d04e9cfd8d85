"""A small, safe Markdown -> HTML converter for the dataset card.

The card (``dataset/merged/README.md``) is written by lerobot and factory: YAML front matter,
headings, bullet lists, fenced code, tables, paragraphs, ``code``, **bold**, *emphasis* and
links. Everything is escaped: raw HTML in the card (lerobot's badge, which loads images from
the internet) is dropped, so the report stays offline and cannot be injected into. A full
Markdown library would pass raw HTML through, which is why this exists.
"""

from __future__ import annotations

import re
from html import escape
from urllib.parse import quote, urlsplit

_INLINE = re.compile(
    r"`(?P<code>[^`]+)`"
    r"|\*\*(?P<bold>[^*]+)\*\*"
    r"|\[(?P<text>[^\]]+)\]\((?P<href>[^)\s]+)\)"
    r"|(?<![\w*])\*(?P<em>[^*\s][^*]*)\*"
)


def _href(url: str, base: str) -> str | None:
    """A safe link target: http(s) and mailto as they are, relative paths under ``base``."""
    parts = urlsplit(url)
    if parts.scheme in ("http", "https", "mailto"):
        return url
    if parts.scheme or url.startswith(("/", "\\")) or ".." in url.split("/"):
        return None
    return f"{base}{quote(url, safe='/#?=&')}" if base else quote(url, safe="/#?=&")


def inline(text: str, base: str = "") -> str:
    """Escapes ``text`` and renders its inline markup (code, bold, emphasis, links)."""
    out: list[str] = []
    pos = 0
    for m in _INLINE.finditer(text):
        out.append(escape(text[pos : m.start()]))
        if m["code"] is not None:
            out.append(f"<code>{escape(m['code'])}</code>")
        elif m["bold"] is not None:
            out.append(f"<strong>{inline(m['bold'], base)}</strong>")
        elif m["em"] is not None:
            out.append(f"<em>{inline(m['em'], base)}</em>")
        else:
            href = _href(m["href"], base)
            label = inline(m["text"], base)
            out.append(f'<a href="{escape(href)}">{label}</a>' if href else label)
        pos = m.end()
    out.append(escape(text[pos:]))
    return "".join(out)


def _table_row(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def markdown_to_html(text: str, base: str = "") -> str:
    """Converts a Markdown document to HTML.

    Args:
        text: the Markdown (YAML front matter at the top is left out).
        base: prefix of relative link targets (the card's folder relative to the page, with a
            trailing ``/``).

    Returns:
        an HTML fragment; all text escaped, raw HTML blocks dropped.
    """
    lines = text.replace("\r\n", "\n").split("\n")
    if lines and lines[0].strip() == "---":
        end = next((i for i in range(1, len(lines)) if lines[i].strip() == "---"), None)
        if end is not None:
            lines = lines[end + 1 :]
    out: list[str] = []
    i = 0
    para: list[str] = []

    def flush() -> None:
        if para:
            out.append(f"<p>{inline(' '.join(para), base)}</p>")
            para.clear()

    while i < len(lines):
        line = lines[i]
        stripped = line.strip()
        if stripped.startswith("```"):
            flush()
            lang = stripped[3:].strip()
            body: list[str] = []
            i += 1
            while i < len(lines) and not lines[i].strip().startswith("```"):
                body.append(lines[i])
                i += 1
            cls = f' class="language-{escape(lang)}"' if lang else ""
            out.append(f"<pre><code{cls}>{escape(chr(10).join(body))}</code></pre>")
            i += 1
            continue
        if not stripped:
            flush()
            i += 1
            continue
        if stripped.startswith("<"):  # a raw HTML block: dropped up to the next blank line
            flush()
            while i < len(lines) and lines[i].strip():
                i += 1
            continue
        heading = re.match(r"(#{1,6})\s+(.*)", stripped)
        if heading:
            flush()
            level = min(6, len(heading[1]) + 2)  # the card's h1 sits below the page's h2
            out.append(f"<h{level}>{inline(heading[2].rstrip('#').strip(), base)}</h{level}>")
            i += 1
            continue
        if re.match(r"[-*+]\s+", stripped):
            flush()
            items: list[str] = []
            while i < len(lines) and re.match(r"\s*[-*+]\s+", lines[i]):
                items.append(re.sub(r"^\s*[-*+]\s+", "", lines[i]))
                i += 1
                while i < len(lines) and lines[i].startswith("  ") and lines[i].strip():
                    items[-1] += " " + lines[i].strip()
                    i += 1
            out.append("<ul>" + "".join(f"<li>{inline(t, base)}</li>" for t in items) + "</ul>")
            continue
        if (
            stripped.startswith("|")
            and i + 1 < len(lines)
            and re.fullmatch(r"\|?\s*:?-+:?\s*(\|\s*:?-+:?\s*)*\|?", lines[i + 1].strip())
        ):
            flush()
            head = _table_row(stripped)
            i += 2
            rows: list[list[str]] = []
            while i < len(lines) and lines[i].strip().startswith("|"):
                rows.append(_table_row(lines[i]))
                i += 1
            out.append(
                "<table><thead><tr>"
                + "".join(f"<th>{inline(c, base)}</th>" for c in head)
                + "</tr></thead><tbody>"
                + "".join(
                    "<tr>" + "".join(f"<td>{inline(c, base)}</td>" for c in r) + "</tr>"
                    for r in rows
                )
                + "</tbody></table>"
            )
            continue
        para.append(stripped)
        i += 1
    flush()
    return "\n".join(out)
