"""Packaging beyond pyproject.toml: the grammar and the standard library ship inside physdsl.

``grammar/`` and ``stdlib/`` stay at the repository root (they are the language, read by
people as much as by the parser) and are installed as ``physdsl/grammar`` and
``physdsl/stdlib``; ``physdsl/syntax/shipped.py`` finds them in a wheel and in a checkout.
"""
from setuptools import find_packages, setup

setup(
    packages=find_packages(include=["physdsl*"])
    + ["physdsl.grammar", "physdsl.stdlib", "physdsl.stdlib.effects"],
    package_dir={"physdsl.grammar": "grammar", "physdsl.stdlib": "stdlib"},
    package_data={"physdsl.grammar": ["*.lark"], "physdsl.stdlib": ["*.phys"],
                  "physdsl.stdlib.effects": ["*.phys"]},
)
