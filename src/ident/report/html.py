"""Markdown-ish text to one self-contained HTML page (figures embedded as base64 PNG).

Reports are written once as Markdown (``report.md``, readable in a terminal or on a forge)
and converted here to ``report.html``, which needs no network and no other file: images are
inlined as ``data:`` URIs. Links to sibling files (``replay.html``, CSVs) stay relative.

The supported subset is what the report writers emit:

- ``#`` to ``######`` headings;
- paragraphs (consecutive non-blank lines);
- ``-`` / ``*`` bullet lists (one level);
- pipe tables (``| a | b |`` with a ``|---|---|`` separator line; ``:---``, ``---:``,
  ``:---:`` align a column left, right or centre);
- fenced code blocks (three backticks);
- ``> `` block quotes (used for warnings);
- inline: ```code```, ``**bold**``, ``*italic*``, ``[text](href)``, ``![alt](src)``.

Everything else is escaped and shown as text, so a report can never inject markup.
"""

from __future__ import annotations

import base64
import html
import re
from collections.abc import Mapping
from pathlib import Path

__all__ = ["embed_png", "markdown_to_html"]

_CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; margin: 1.2em auto;
       max-width: 80em; padding: 0 1em; color: #222; line-height: 1.4; }
h1, h2, h3 { line-height: 1.2; } h1 { font-size: 1.6em; margin: .3em 0; }
h2 { border-bottom: 1px solid #ddd; padding-bottom: .2em; }
table { border-collapse: collapse; margin: .8em 0; font-size: .9em; max-width: 100%; }
th, td { border: 1px solid #ccc; padding: .25em .6em; text-align: left; vertical-align: top;
         overflow-wrap: break-word; word-break: normal; hyphens: manual; }
td code { overflow-wrap: anywhere; }
th { background: #f3f3f3; }
h2#summary + table td:first-child { font-weight: 600; white-space: normal; width: 16em; }
h2#summary + table { font-size: 1em; }
code, pre { font-family: ui-monospace, "DejaVu Sans Mono", monospace; font-size: .9em; }
pre { background: #f6f6f6; padding: .8em; overflow-x: auto; white-space: pre-wrap; }
blockquote { border-left: 4px solid #d9822b; background: #fff6ec; margin: 1em 0;
             padding: .4em 1em; }
img { max-width: 100%; height: auto; }
.missing { color: #a00; }
"""

_TABLE_SEP = re.compile(r"^\s*\|?\s*:?-+:?\s*(\|\s*:?-+:?\s*)*\|?\s*$")
_HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
_BULLET = re.compile(r"^\s*[-*]\s+(.*)$")
_INLINE = re.compile(
    r"(?P<img>!\[(?P<alt>[^\]]*)\]\((?P<src>[^)\s]+)\))"
    r"|(?P<link>\[(?P<text>[^\]]+)\]\((?P<href>[^)\s]+)\))"
    r"|(?P<code>`(?P<codetext>[^`]+)`)"
    r"|(?P<bold>\*\*(?P<boldtext>.+?)\*\*)"
    r"|(?P<em>(?<![\w*])\*(?P<emtext>[^*\s](?:[^*]*[^*\s])?)\*(?![\w*]))"
)


def embed_png(png: bytes, alt: str = "") -> str:
    """An ``<img>`` element holding ``png`` as a base64 data URI."""
    data = base64.b64encode(png).decode("ascii")
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


def markdown_to_html(
    markdown: str,
    *,
    title: str,
    images: Mapping[str, bytes] | None = None,
    base_dir: str | Path | None = None,
) -> str:
    """Convert the Markdown subset of the module docstring to a self-contained HTML page.

    Parameters
    ----------
    markdown :
        The report text.
    title :
        Page title.
    images :
        PNG bytes by image ``src`` as written in the Markdown (``figures/x.png``); looked up
        first.
    base_dir :
        Folder against which other relative PNG ``src`` are read from disk and embedded.
        An image found in neither place is shown as a visible "missing figure" note.

    Returns
    -------
    :
        A complete HTML document (UTF-8 text) with no external resource.
    """
    resolver = _ImageResolver(images or {}, Path(base_dir) if base_dir is not None else None)
    body = "\n".join(_blocks(markdown.splitlines(), resolver))
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f"<title>{html.escape(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
        f"{body}\n</body>\n</html>\n"
    )


class _ImageResolver:
    def __init__(self, images: Mapping[str, bytes], base_dir: Path | None) -> None:
        self.images = images
        self.base_dir = base_dir

    def __call__(self, src: str, alt: str) -> str:
        png = self.images.get(src)
        if png is None and self.base_dir is not None and not re.match(r"^[a-z]+:", src):
            path = self.base_dir / src
            if path.is_file() and path.suffix.lower() == ".png":
                png = path.read_bytes()
        if png is None:
            return f'<span class="missing">[missing figure: {html.escape(src)}]</span>'
        return embed_png(png, alt)


def _inline(text: str, resolver: _ImageResolver) -> str:
    out: list[str] = []
    pos = 0
    for m in _INLINE.finditer(text):
        out.append(html.escape(text[pos : m.start()]))
        if m.group("img"):
            out.append(resolver(m.group("src"), m.group("alt")))
        elif m.group("link"):
            href = m.group("href")
            if re.match(r"^\s*javascript:", href, re.IGNORECASE):
                out.append(html.escape(m.group(0)))
            else:
                label = _inline(m.group("text"), resolver)
                out.append(f'<a href="{html.escape(href)}">{label}</a>')
        elif m.group("code"):
            out.append(f"<code>{html.escape(m.group('codetext'))}</code>")
        elif m.group("bold"):
            out.append(f"<strong>{_inline(m.group('boldtext'), resolver)}</strong>")
        else:
            out.append(f"<em>{_inline(m.group('emtext'), resolver)}</em>")
        pos = m.end()
    out.append(html.escape(text[pos:]))
    return "".join(out)


def _cells(line: str) -> list[str]:
    line = line.strip()
    if line.startswith("|"):
        line = line[1:]
    if line.endswith("|") and not line.endswith("\\|"):
        line = line[:-1]
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", line)]


def _alignment(separator: str) -> str:
    """``:---`` left, ``---:`` right, ``:---:`` center, ``---`` the stylesheet's default."""
    left, right = separator.startswith(":"), separator.endswith(":")
    return "center" if left and right else "left" if left else "right" if right else ""


def _cell(tag: str, align: list[str], k: int, text: str, resolver: _ImageResolver) -> str:
    style = f' style="text-align: {align[k]}"' if k < len(align) and align[k] else ""
    return f"<{tag}{style}>{_inline(text, resolver)}</{tag}>"


def _blocks(lines: list[str], resolver: _ImageResolver) -> list[str]:
    """HTML of each block (code, heading, table, list, quote, paragraph) of markdown lines."""
    out: list[str] = []
    i, n = 0, len(lines)
    while i < n:
        line = lines[i]
        if not line.strip():
            i += 1
            continue
        heading = _HEADING.match(line)
        if line.strip().startswith("```"):
            block, i = _code_block(lines, i)
        elif heading:
            level = len(heading.group(1))
            text = heading.group(2)
            anchor = re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")
            block, i = f'<h{level} id="{anchor}">{_inline(text, resolver)}</h{level}>', i + 1
        elif _table_starts(lines, i):
            block, i = _table_block(lines, i, resolver)
        elif _BULLET.match(line):
            block, i = _list_block(lines, i, resolver)
        elif line.lstrip().startswith(">"):
            block, i = _quote_block(lines, i, resolver)
        else:
            block, i = _paragraph(lines, i, resolver)
        out.append(block)
    return out


def _table_starts(lines: list[str], i: int) -> bool:
    """Whether line i is a table header (a ``|`` line followed by a separator line)."""
    return "|" in lines[i] and i + 1 < len(lines) and bool(_TABLE_SEP.match(lines[i + 1]))


def _code_block(lines: list[str], i: int) -> tuple[str, int]:
    """The fenced code block opening at line i, and the line after its closing fence."""
    j = i + 1
    while j < len(lines) and not lines[j].strip().startswith("```"):
        j += 1
    return "<pre><code>" + html.escape("\n".join(lines[i + 1 : j])) + "</code></pre>", j + 1


def _table_block(lines: list[str], i: int, resolver: _ImageResolver) -> tuple[str, int]:
    """The table whose header is line i, and the line after its last row."""
    n = len(lines)
    header = _cells(lines[i])
    align = [_alignment(c) for c in _cells(lines[i + 1])]
    rows = []
    j = i + 2
    while j < n and lines[j].strip() and "|" in lines[j]:
        rows.append(_cells(lines[j]))
        j += 1
    head = "".join(_cell("th", align, k, c, resolver) for k, c in enumerate(header))
    body = "".join(
        "<tr>" + "".join(_cell("td", align, k, c, resolver) for k, c in enumerate(row)) + "</tr>"
        for row in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>", j


def _list_block(lines: list[str], i: int, resolver: _ImageResolver) -> tuple[str, int]:
    """The bullet list starting at line i, and the line after it."""
    n = len(lines)
    items = []
    while i < n and _BULLET.match(lines[i]):
        items.append(_BULLET.match(lines[i]).group(1))  # type: ignore[union-attr]
        i += 1
        # continuation lines of a list item are indented
        while i < n and lines[i].startswith("  ") and lines[i].strip():
            items[-1] += " " + lines[i].strip()
            i += 1
    return "<ul>" + "".join(f"<li>{_inline(t, resolver)}</li>" for t in items) + "</ul>", i


def _quote_block(lines: list[str], i: int, resolver: _ImageResolver) -> tuple[str, int]:
    """The block quote starting at line i, and the line after it."""
    quoted = []
    while i < len(lines) and lines[i].lstrip().startswith(">"):
        quoted.append(lines[i].lstrip()[1:].strip())
        i += 1
    return f"<blockquote><p>{_inline(' '.join(quoted), resolver)}</p></blockquote>", i


def _paragraph(lines: list[str], i: int, resolver: _ImageResolver) -> tuple[str, int]:
    """The paragraph starting at line i (up to a blank line or another block), and the line
    after it."""
    para = []
    while (
        i < len(lines)
        and lines[i].strip()
        and not _HEADING.match(lines[i])
        and not lines[i].strip().startswith("```")
        and not _BULLET.match(lines[i])
        and not lines[i].lstrip().startswith(">")
        and not _table_starts(lines, i)
    ):
        para.append(lines[i].strip())
        i += 1
    return f"<p>{_inline(' '.join(para), resolver)}</p>", i
