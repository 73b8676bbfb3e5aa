"""What pinarray declares it needs is what CI tests it with."""

import re
import tomllib

from tests.runs import REPO


def floors_declared() -> dict[str, str]:
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    floors = {}
    for requirement in project["dependencies"]:
        name, version = re.fullmatch(r"([A-Za-z0-9_.-]+)>=([0-9.]+)", requirement).groups()
        floors[name.lower()] = version
    return floors


def floors_tested() -> dict[str, str]:
    pins = {}
    for line in (REPO / ".ci" / "floors.txt").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, version = line.split("==")
            pins[name.strip().lower()] = version.strip()
    return pins


def test_every_dependency_has_a_floor_and_ci_tests_exactly_that_floor():
    assert floors_tested() == floors_declared()


def test_the_example_paradigm_package_can_be_installed_beside_this_pinarray():
    # examples/tap_count/ pins the pinarray it was written for; a version bump that leaves it
    # behind makes `make example-paradigm` (CI) fail to install it beside the checkout.
    from packaging.requirements import Requirement

    from pinarray.version import __version__

    project = tomllib.loads((REPO / "examples" / "tap_count" / "pyproject.toml").read_text())
    (requirement,) = [Requirement(text) for text in project["project"]["dependencies"]
                      if Requirement(text).name == "pinarray"]
    assert requirement.specifier.contains(__version__, prereleases=True), (
        f"examples/tap_count asks for pinarray{requirement.specifier}, this is {__version__}")
