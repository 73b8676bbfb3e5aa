"""The documentation holds what the README used to: every command line the old one-page README
gave (tests/readme_commands.txt, taken from it when it became a front page) is on some page of
docs/, and the README stays a front page. The site itself is built strictly by `make docs`."""

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def words(text: str) -> str:
    """Text with shell line continuations joined and every run of whitespace one space."""
    return " ".join(re.sub(r"\\\n", " ", text).split())


def test_every_command_line_of_the_old_readme_is_found_in_the_docs():
    site = " ".join(words(page.read_text(encoding="utf-8")) for page in (REPO / "docs").rglob("*.md"))
    commands = (REPO / "tests" / "readme_commands.txt").read_text(encoding="utf-8").splitlines()
    assert [c for c in commands if words(c) not in site] == []


def test_the_readme_is_a_front_page_that_links_to_pages_that_exist():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 150
    assert "make run" in readme and "make test" in readme
    targets = re.findall(r"\]\(((?!https?:)[^)#]+)", readme)
    assert targets and [t for t in targets if not (REPO / t).exists()] == []


def test_the_protocol_guide_s_own_device_stimulus_and_design_make_a_protocol_that_validates(tmp_path, capsys):
    """A newcomer writes a first protocol by copying the guide's `device`, its first `stimuli`
    and its first `design` example into one file: that file must validate (the seed's train at
    10 Hz on the guide's calibration), not be refused as a stroke the servo cannot make."""
    from pinarray.cli import main

    guide = (REPO / "protocols" / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```yaml\n(.*?)```", guide, flags=re.S)
    first = {key: next(b for b in blocks if b.startswith(key + ":")) for key in ("device", "stimuli", "design")}
    protocol = tmp_path / "first.yaml"
    protocol.write_text("protocol: first\n" + first["device"] + first["stimuli"] + first["design"], encoding="utf-8")
    assert main(["validate", str(protocol)]) == 0, capsys.readouterr().err


def shown_command_lines() -> list[tuple[str, str]]:
    """Every whole command line a page shows to be typed: the `pinarray ...` lines of its code
    blocks (fenced or indented), continuations joined, a trailing `# comment` dropped."""
    shown = []
    for page in sorted((REPO / "docs").rglob("*.md")):
        text = page.read_text(encoding="utf-8")
        blocks = re.findall(r"```[a-z]*\n(.*?)```", text, flags=re.S)
        blocks += ["\n".join(line[4:] for line in indented.splitlines())
                   for indented in re.findall(r"(?:^    \S.*\n)+", text, flags=re.M)]
        for block in blocks:
            for line in re.sub(r"\\\n\s*", " ", block).splitlines():
                if line.startswith("pinarray "):
                    shown.append((page.name, line.split(" # ")[0].strip()))
    return shown


def test_every_command_line_a_page_shows_is_one_pinarray_accepts():
    """A newcomer copies a page's command as written: its command and options must exist and
    go together (a `batch` without an answer source is refused before anything runs)."""
    import shlex

    from pinarray.cli import build_parser

    refused = []
    lines = shown_command_lines()
    for page, line in lines:
        try:
            build_parser().parse_args(shlex.split(line)[1:])
        except SystemExit:
            refused.append((page, line))
    assert len(lines) >= 5 and refused == []


def test_the_resume_line_the_pages_and_the_results_readme_give_is_one_batch_accepts():
    """The line a lab copies to continue a killed run, its placeholders filled in, is accepted:
    `batch` asks for the answers' option on a resume too."""
    import shlex

    from pinarray.cli import build_parser
    from pinarray.journal.dataset import DATASET_README

    texts = [page.read_text(encoding="utf-8") for page in (REPO / "docs").rglob("*.md")] + [DATASET_README]
    lines = [line for text in texts for line in re.findall(r"`(pinarray batch [^`(]*--resume)`", words(text))]
    filled = {"FILE": "protocols/demo.yaml", "ID": "01", "MODEL": "default", "CSV": "answers.csv"}
    refused = []
    for line in lines:
        try:
            build_parser().parse_args([filled.get(word, word) for word in shlex.split(line)[1:]])
        except SystemExit:
            refused.append(line)
    assert len(lines) >= 2 and refused == []
