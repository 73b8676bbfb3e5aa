"""pinarray's version, in one place: the package's metadata (pyproject.toml reads it here), the
results' manifests and sidecars, ``pinarray --version`` and `pinarray.__version__`.

Semantic versioning of the public face (what `pinarray.__all__` lists; CHANGELOG.md): a
change that breaks a script raises the major number (the minor one before 1.0), a new name
the minor one (the patch one before 1.0). tests/test_public_api.py holds the rule.
"""

__version__ = "0.5.2"
