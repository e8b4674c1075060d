"""The README is a user's guide: its Python examples run, it stays short, its command table
names every command of ``flexparcel --help``, and neither it nor docs/ is a dated work log."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = sorted((ROOT / "docs").glob("*.md"))
MAX_README_BYTES = 20_000

_FENCE = re.compile(r"^```python[ \t]*\n(.*?)^```[ \t]*$", re.MULTILINE | re.DOTALL)


def python_blocks(text: str) -> list[str]:
    """The ```python fenced blocks of a Markdown text, in order."""
    return [m.group(1) for m in _FENCE.finditer(text)]


def test_readme_python_blocks_run_in_order(tmp_path, monkeypatch):
    blocks = python_blocks(README.read_text(encoding="utf-8"))
    assert blocks, "README.md has no ```python block"
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__readme__"}
    for k, code in enumerate(blocks, start=1):
        try:
            exec(compile(code, f"README.md python block {k}", "exec"), namespace)
        except Exception as exc:  # name the block that failed
            raise AssertionError(f"README.md python block {k} failed: {exc!r}") from exc


def test_readme_is_at_most_20_kb():
    size = len(README.read_text(encoding="utf-8").encode())
    assert size <= MAX_README_BYTES, f"README.md is {size} bytes (limit {MAX_README_BYTES})"


def test_readme_opens_with_the_two_make_commands():
    text = README.read_text(encoding="utf-8")
    first_block = re.search(r"```bash\n(.*?)```", text, re.DOTALL)
    assert first_block is not None
    commands = [
        line.split("#")[0].strip()
        for line in first_block.group(1).splitlines()
        if line.split("#")[0].strip()
    ]
    assert commands == ["make demo", "make test"]
    before = text[: first_block.start()].strip().splitlines()
    assert len([line for line in before if line.strip()]) <= 2  # a title and one line


@pytest.mark.parametrize("path", [README, *DOCS], ids=lambda p: p.name)
def test_no_work_log_wording(path):
    text = path.read_text(encoding="utf-8")
    session = re.search(r"\bsessions?\b", text, re.IGNORECASE)
    assert session is None, f"{path.name}: {text[session.start() - 40 : session.end() + 40]!r}"
    date = re.search(r"\b20\d\d-[01]\d-[0-3]\d\b", text)
    assert date is None, f"{path.name}: dated entry {date.group(0)!r}"


def _help_commands() -> list[str]:
    """The commands that ``flexparcel --help`` lists."""
    out = subprocess.run(
        [sys.executable, "-m", "flexparcel.cli", "--help"],
        capture_output=True,
        text=True,
        check=True,
        cwd=ROOT,
    ).stdout
    block = out.split("positional arguments:", 1)[1].split("options:", 1)[0]
    names = re.findall(r"^ {4}([a-z][a-z0-9-]*)\b", block, re.MULTILINE)
    assert names, f"no commands found in flexparcel --help:\n{out}"
    return names


def _readme_command_table() -> list[str]:
    """First words after ``flexparcel`` in the first column of the README's command table."""
    text = README.read_text(encoding="utf-8")
    section = text.split("## Commands", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"^\| `flexparcel ([a-z][a-z0-9-]*)", section, re.MULTILINE)


def test_readme_command_table_names_every_command_of_help():
    helped = _help_commands()
    table = _readme_command_table()
    missing = [c for c in helped if c not in table]
    assert not missing, f"commands of flexparcel --help missing in the README table: {missing}"
    unknown = [c for c in table if c not in helped]
    assert not unknown, f"README table names commands flexparcel --help does not: {unknown}"


def test_readme_explains_every_extra():
    # each extra of pyproject.toml has its row in the README's table of extras: what it
    # pulls in and what it is needed for
    import tomllib

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"
    ]
    rows = re.findall(r"^\| `([a-z]+)` \| [^|]+ \| [^|]+ \|$", README.read_text(), re.MULTILINE)
    missing = sorted(set(extras) - set(rows))
    assert not missing, f"README.md's table of extras lacks: {missing}"
