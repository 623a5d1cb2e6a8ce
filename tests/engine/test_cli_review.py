"""``handover plan --rrd`` and ``handover review FILE``, through the command line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from handover.engine.cli.app import main
from handover.engine.cli.review import viewer_command


@pytest.fixture(scope="module")
def knife_rrd(tmp_path_factory) -> tuple[Path, dict]:
    """A recording of the knife plan written by ``handover plan``, and the plan's JSON."""
    folder = tmp_path_factory.mktemp("review")
    rrd, out = folder / "knife.rrd", folder / "knife.json"
    code = main(["plan", "knife", "--rrd", str(rrd), "-o", str(out)])
    assert code in (0, 4)
    return rrd, json.loads(out.read_text())


def test_review_summary_names_entities_stages_and_trace(knife_rrd, capsys):
    rrd, result = knife_rrd
    assert main(["review", str(rrd), "--summary"]) == 0
    text = capsys.readouterr().out
    assert "world/handover/candidates/centres" in text and "trace/log" in text
    assert "0 generated" in text
    assert f"{result['candidates']['grasps']} candidates" in text
    for entry in result["trace"]:
        assert entry["rule"] in text


def test_review_json_counts_agree_with_the_plan(knife_rrd, capsys):
    rrd, result = knife_rrd
    assert main(["review", str(rrd), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    stages = {s["stage"]: s for s in data["stages"]}
    assert stages[0]["outcomes"] == {"generated": result["candidates"]["grasps"]}
    if result["feasible"]:
        assert stages[4]["outcomes"]["chosen"] >= 1
        handover = [t for t in data["trace"] if t["stage"] in (4, 5)]
        assert len(handover) == len(result["trace"])
    else:
        assert any(result["reason"] in t["text"] for t in data["trace"] if t["level"] == "ERROR")


def test_review_without_display_prints_the_summary(knife_rrd, capsys, monkeypatch):
    rrd, _ = knife_rrd
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    if sys.platform in ("darwin", "win32"):
        pytest.skip("a display is always there on macOS and Windows")
    assert main(["review", str(rrd)]) == 0
    captured = capsys.readouterr()
    assert "no viewer can run here" in captured.err
    assert "stages:" in captured.out


def test_review_with_a_viewer_spawns_it_and_returns(knife_rrd, capsys, monkeypatch):
    rrd, _ = knife_rrd
    started = []

    class FakePopen:
        pid = 4242

        def __init__(self, command, **kwargs):
            started.append((command, kwargs))

    monkeypatch.setattr(
        "handover.engine.cli.review.viewer_command", lambda path: ["rerun", str(path)]
    )
    monkeypatch.setattr(subprocess, "Popen", FakePopen)
    assert main(["review", str(rrd)]) == 0
    assert started == [(["rerun", str(rrd)], started[0][1])]
    assert started[0][1]["start_new_session"] is True  # detached: the command does not wait
    assert "pid 4242" in capsys.readouterr().out


def test_viewer_needs_a_display_and_the_binary(tmp_path):
    if sys.platform in ("darwin", "win32"):
        pytest.skip("a display is always there on macOS and Windows")
    rrd = tmp_path / "a.rrd"
    assert viewer_command(rrd, env={"PATH": ""}) is None  # no display
    command = viewer_command(rrd, env={"DISPLAY": ":0", "PATH": ""})
    beside = Path(sys.executable).parent / "rerun"
    assert command == ([str(beside), str(rrd)] if beside.is_file() else None)


@pytest.mark.parametrize("content", [None, "plain text, not a recording\n"])
def test_review_of_a_missing_or_foreign_file_is_a_usage_error(tmp_path, capsys, content):
    path = tmp_path / "x.rrd"
    if content is not None:
        path.write_text(content)
    assert main(["review", str(path), "--summary"]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and ("does not exist" in err or "not a readable" in err)
