"""docs/settings.md, generated from the typed settings' own documentation (settings.py), the
presets (presets.py) and the migrations (settings_upgrade.py):
`python -m omninav.settings_doc > docs/settings.md`; tests/engine/test_settings.py fails when the page is
not current.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from dataclasses import fields
from typing import Any

from .settings import STAGES, Rule, field_default
from .settings_upgrade import MIGRATIONS, VERSION, current_confidence


def _default_text(v: Any) -> str:
    import json

    return "null" if v is None else json.dumps(v)


def markdown(presets: Mapping[str, Mapping[str, Any]] | None = None) -> str:
    """docs/settings.md: every key by stage, with its meaning, unit, range and default; and each
    preset's settings where given (presets.PRESETS)."""
    out = [
        "# Venue settings",
        "",
        "Generated from `backend/omninav/settings.py` by `python -m omninav.settings_doc > docs/settings.md`;",
        "tests/engine/test_settings.py fails when this page is not current. Every venue stores the settings it",
        f"was modelled with (`settings.json` of each generation, format version {VERSION}); a preset",
        "(`presets.py`) sets some of them; a venue modelled by an earlier release is read through the",
        "numbered migrations of `settings_upgrade.upgrade`.",
        "",
    ]
    for cls, title in STAGES:
        out += [f"## {title[0].upper()}{title[1:]}", "", " ".join((cls.__doc__ or "").split()), ""]
        out += ["| key | meaning | unit | accepts | default |", "| --- | --- | --- | --- | --- |"]
        for f in fields(cls):
            r: Rule = f.metadata["rule"]
            d = field_default(f)
            out.append(f"| `{f.name}` | {r.doc} | {r.unit} | {r.range_text()} | `{_default_text(d)}` |")
        out.append("")
    if presets:
        out += ["## Presets", "", "What each preset (`presets.PRESETS`) sets over the defaults above.", ""]
        out += ["| preset | sets |", "| --- | --- |"]
        for name, over in presets.items():
            sets = "; ".join(f"`{k}` {_default_text(v)}" for k, v in over.items()) or "(the defaults)"
            out.append(f"| `{name}` | {sets} |")
        out.append("")
    out += ["## Migrations", ""]
    for i, step in enumerate(MIGRATIONS, 1):
        doc = " ".join((step.__doc__ or "").split())
        out.append(f"- {doc}" if doc.startswith(f"{i}:") else f"- {i}: {doc}")
    out.append(f"- {' '.join((current_confidence.__doc__ or '').split())}")
    out.append("")
    return "\n".join(out)


if __name__ == "__main__":
    from .presets import PRESETS

    sys.stdout.write(markdown(PRESETS))
