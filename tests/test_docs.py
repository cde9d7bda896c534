"""The repository's documents stay a size a reader can use and point only at what exists.

README.md is a user's guide (at most 16 KB, the two commands in its first 40 lines);
docs/benchmarks.md holds today's figures (at most 40 KB; the notebook before is docs/benchlog.md);
and a path a document, docstring or comment names is a file the repository has. A path is read
from the repository's root, from `backend/omninav/` (the package's modules are named as
`calib/ring.py`) or from `web/` (its tests as `tests/golden.test.ts`).
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BASES = (ROOT, ROOT / "backend" / "omninav", ROOT / "web")
PATH = re.compile(
    r"(?<![\w/.-])((?:docs|calib|bench|tests|web|e2e|backend|scripts|\.ci)/[\w./-]*\w"
    r"\.(?:md|py|ts|mjs|cjs|json|sh|html|xml|toml))"
)
EXAMPLES = {"bench/NAME.py", "bench/NAME.mjs"}  # placeholders in sentences, not files
BINARY = (".png", ".jpg", ".y4m", ".mp4", ".npy", ".gz", ".wasm", ".ico", ".pgm", ".woff2")


def _tracked() -> list[str]:
    out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True)
    return [f for f in out.stdout.split() if not f.endswith(BINARY)]


def missing_paths(files: list[str], folder: Path = ROOT) -> dict[str, list[str]]:
    """Each path the files (in `folder`) name that resolves against none of BASES, with the files
    that name it."""
    missing: dict[str, list[str]] = {}
    for name in files:
        try:
            text = (folder / name).read_text(encoding="utf-8")
        except (UnicodeDecodeError, FileNotFoundError):
            continue
        for m in PATH.finditer(text):
            path = m.group(1)
            if path in EXAMPLES or any((base / path).exists() for base in BASES):
                continue
            missing.setdefault(path, []).append(name)
    return missing


def test_readme_is_a_users_guide_with_the_two_commands_first() -> None:
    readme = (ROOT / "README.md").read_bytes()
    assert len(readme) <= 16 * 1024
    head = readme.decode().splitlines()[:40]
    assert any("npm start" in line for line in head)
    assert any("npm test" in line for line in head)


def test_benchmarks_holds_todays_figures_within_40_kb() -> None:
    text = (ROOT / "docs" / "benchmarks.md").read_text()
    assert len(text.encode()) <= 40 * 1024
    assert "## Today in one table" in text


def test_no_document_or_comment_names_a_file_the_repository_lacks() -> None:
    assert missing_paths(_tracked()) == {}


def test_a_named_path_that_does_not_exist_is_caught(tmp_path: Path) -> None:
    gone = "docs/" + "CONVENTIONS.md"  # (spelt in two pieces: this file names no missing path)
    (tmp_path / "note.md").write_text(f"See {gone}, calib/ring.py and docs/formats.md.\n")
    assert missing_paths(["note.md"], tmp_path) == {gone: ["note.md"]}
