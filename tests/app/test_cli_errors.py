"""Command-line errors (issue 12, row 15): a bad option value is a one-line error with exit 2,
and every ``--json`` option says what it does."""

from __future__ import annotations

import argparse

import pytest

from app import cli


def test_bench_with_an_unknown_area_is_an_error_naming_the_known_ones(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["bench", "--only", "nosuch"]) == 2
    err = capsys.readouterr().err
    assert "nosuch" in err and "scanner" in err
    assert err.count("\n") == 1


def _subparsers(parser: argparse.ArgumentParser) -> list[tuple[str, argparse.ArgumentParser]]:
    found: list[tuple[str, argparse.ArgumentParser]] = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                found.append((name, sub))
                found += [(f"{name} {n}", p) for n, p in _subparsers(sub)]
    return found


def test_every_json_option_has_a_help_text() -> None:
    parser = cli.build_parser(cli.load_modules())
    commands = _subparsers(parser)
    with_json = [(name, a) for name, sub in commands for a in sub._actions if "--json" in a.option_strings]
    assert len(with_json) >= 4
    missing = [name for name, action in with_json if not action.help]
    assert missing == []
