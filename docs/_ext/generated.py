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
            _pages(self.env).add(self.env.docname)
            out = []
            for label, title, body in sections():
                section = nodes.section()
                section["names"].append(label)
                self.state.document.note_explicit_target(section, section)
                section += nodes.title(title, title)
                self.state.nested_parse(StringList(body.splitlines(), source), self.content_offset, section)
                out.append(section)
            return out

    return Sections


def _pages(env) -> set:
    """The pages with generated sections (kept in the build environment)."""
    if not hasattr(env, "swe_generated_pages"):
        env.swe_generated_pages = set()
    return env.swe_generated_pages


def _outdated(app, env, added, changed, removed) -> list[str]:
    # their sources (the schema, the registry, the writers) are code, not pages: read them every build
    return sorted(_pages(env) - set(removed))


def add(app, name: str, sections: Callable[[], list[tuple[str, str, str]]], source: str) -> dict:
    """Register the directive ``name`` of ``sections`` with ``app``; its pages are read again
    at every build. Returns the extension's metadata."""
    app.add_directive(name, directive(sections, source))
    if _outdated not in [listener.handler for listener in app.events.listeners.get("env-get-outdated", [])]:
        app.connect("env-get-outdated", _outdated)
    return {"parallel_read_safe": True}
