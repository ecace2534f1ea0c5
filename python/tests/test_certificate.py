"""Certificates read back (docs/FORMAT.md §13.3): a DCC written by ``polycal report --dcc``
is read wherever the package reads a result file, as the command line reads it. Numbers are
checked against the command line's JSON of the same comparison (the same library, another
path through it); refusals carry the command line's message."""

import json
import subprocess

import pytest

import polycal
from test_polycal import BUDGET, DATA, _binary, cli

META = DATA.parent.parent / "report" / "meta.toml"


def _certificate(tmp_path):
    """RESULT.csv and CERT.xml of one evaluation, by the command line."""
    csv = tmp_path / "result.csv"
    out = subprocess.run(
        [_binary(), "solve", str(DATA), "--budget", str(BUDGET), "--format", "csv"],
        capture_output=True,
        check=True,
    )
    csv.write_bytes(out.stdout)
    xml = tmp_path / "cert.xml"
    subprocess.run(
        [
            _binary(), "report", str(DATA), "--budget", str(BUDGET), "--meta", str(META),
            "--out", str(tmp_path / "r.html"), "--dcc", str(xml),
        ],
        capture_output=True,
        check=True,
    )
    return csv, xml


def test_a_certificate_is_read_where_a_result_file_is(tmp_path):
    csv, xml = _certificate(tmp_path)
    assert len(polycal.read_results(xml)._inner) == 73
    compared = polycal.compare(csv, xml).to_dict()
    expected = json.loads(cli("compare", csv, xml, "--format", "json"))
    for key in ("rows", "max_abs_en", "verdict", "vector"):
        assert compared[key] == expected[key], key
    assert compared["max_abs_en"] < 0.1 and compared["vector"]["consistent"] is True


def test_a_hostile_certificate_is_refused_with_the_command_lines_message(tmp_path):
    bomb = tmp_path / "bomb.xml"
    bomb.write_text('<?xml version="1.0"?>\n<!DOCTYPE a [<!ENTITY x "xx">]>\n<a>&x;</a>\n')
    with pytest.raises(polycal.InputError) as refused:
        polycal.read_results(bomb)
    out = subprocess.run(
        [_binary(), "compare", str(bomb), str(bomb)], capture_output=True, text=True
    )
    assert (refused.value.path, refused.value.line) == (str(bomb), 2)
    assert out.returncode == 2
    assert out.stderr.strip() == f"error: {refused.value}"
