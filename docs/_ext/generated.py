"""What the generated reference pages share: a directive of sections made from (label, title,
body) triples, each body reStructuredText parsed in place, each section a label other pages can
``:ref:``. Sphinx is imported here only, so that the pages' contents (``scene_keys.sections``,
``steppers_page.sections``) can be read and tested without it."""

from __future__ import annotations

from collections.abc import Callable

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.util.docutils import SphinxDirective


def directive(sections: Callable[[], list[tuple[str, str, str]]], source: str) -> type[SphinxDirective]:
    """A directive (no arguments, no content) that builds a section for each triple of
    ``sections()``; ``source`` names where its text comes from in warnings. The sections are
    built here, not parsed from generated titles, so that each label names its own section (a
    label parsed before a generated title lands in the previous section)."""

    class Sections(SphinxDirective):
        def run(self) -> list[nodes.Node]:
            out = []
            for label, title, body in sections():
                section = nodes.section()
                section["names"].append(label)
                self.state.document.note_explicit_target(section, section)
                section += nodes.title("", "", nodes.literal(title, title))
                self.state.nested_parse(StringList(body.splitlines(), source), self.content_offset, section)
                out.append(section)
            return out

    return Sections
