"""``handover kb test``, ``--coverage`` and ``handover compare``, through the command line.

The shipped KB's own cases must pass; cases written by the tests into a copy of the KB show
a failing expectation (exit 1, expected vs got) and an invalid test file (exit 3, file:line).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from handover.engine.cli.app import main
from handover.engine.load.loader import load_kb
from handover.engine.store.kb import builtin_kb_dir


def run(capsys, *args: str) -> tuple[int, str, str]:
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def kb_copy(tmp_path: Path) -> Path:
    """The built-in KB copied, without its own test files."""
    root = tmp_path / "kb"
    shutil.copytree(builtin_kb_dir(), root)
    shutil.rmtree(root / "tests")
    return root


def write_tests(root: Path, text: str, name: str = "mine") -> Path:
    path = root / "tests" / f"{name}.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def test_the_shipped_cases_pass_and_cover_every_object_and_receiver_rule(capsys):
    code, out, _ = run(capsys, "kb", "test", "--json")
    report = json.loads(out)
    assert code == 0, [c for c in report["cases"] if not c["passed"]]
    assert report["failed"] == 0 and report["passed"] == len(report["cases"]) >= 20
    kb = load_kb()
    cases = [case for tf in kb.tests.values() for case in tf.cases]
    assert {c.query.object for c in cases} == set(kb.objects)
    # every rule about a receiver's role is expected somewhere to apply (to pass, or to be
    # scored for a soft rule: a preference such as two hands for an elder)
    role_rules = {r.id for c in kb.cultures.values() for r in c.rules if r.applies.receiver_roles}
    assert role_rules
    passing = {rule for c in cases for rule, status in c.expect.rules.items()
               if status in ("pass", "scored")}
    assert role_rules <= passing


def test_a_false_expectation_fails_with_expected_got_and_the_deciding_rules(capsys, kb_copy):
    write_tests(kb_copy, """\
        id: mine
        cases:
          - name: a knife with its tip at the receiver
            query: {object: knife}
            expect:
              mode: H2G1
              receiver_parts_any: [blade]
              axes: {tip: {toward_receiver: "<= 30"}}
              rules: {sharp_tip_away: fail}
          - name: the knife as it is
            query: {object: knife}
            expect: {outcome: handover}
        """.replace("        ", "", 1).replace("\n        ", "\n"))
    code, out, _ = run(capsys, "--kb", str(kb_copy), "kb", "test")
    assert code == 1
    assert "FAIL tests/mine.yaml:3 a knife with its tip at the receiver" in out
    assert "PASS tests/mine.yaml:10 the knife as it is" in out
    assert "mode: mode H1G1, expected H2G1" in out
    assert "the receiver holds handle, expected a part named or tagged blade" in out
    assert "angle(tip, toward_receiver) = 180.0 deg, expected <= 30" in out
    assert "rule sharp_tip_away is pass, expected fail" in out
    assert "sharp_tip_away pass" in out and "etiquette/common.yaml:" in out  # decided by
    assert "1 passed, 1 failed" in out
    code, out, _ = run(capsys, "--kb", str(kb_copy), "kb", "test", "--json")
    report = json.loads(out)
    assert code == 1 and (report["passed"], report["failed"]) == (1, 1)
    bad = report["cases"][0]
    assert bad["file"] == "tests/mine.yaml" and bad["line"] == 3 and not bad["passed"]
    assert [f["expect"] for f in bad["failures"]] == [
        "mode", "receiver_parts_any", "axes.tip.toward_receiver", "rules.sharp_tip_away"]
    assert bad["failures"][0]["expected"] == "H2G1" and bad["failures"][0]["got"] == "H1G1"


@pytest.mark.parametrize("expect, message", [
    ('{axes: {tip: {toward_receiver: "about 90"}}}', "is not an angle comparison"),
    ("{axes: {spout: {up: '<= 20'}}}", "object 'knife' has no axis 'spout'"),
    ("{robot_parts_none: [sharpp]}", "no part or tag 'sharpp'"),
    ("{rules: {two_hands_for_elders: pass}}", "not in force in culture 'common'"),
    ("{mode: H3G3}", "mode: must be one of"),
    ("{}", "expect nothing?"),
])
def test_an_invalid_test_file_is_an_invalid_kb_at_file_line(capsys, kb_copy, expect, message):
    write_tests(kb_copy, "id: mine\ncases:\n  - name: x\n    query: {object: knife}\n"
                         f"    expect: {expect}\n")
    code, _, err = run(capsys, "--kb", str(kb_copy), "kb", "test")
    assert code == 3
    assert "tests/mine.yaml:5:" in err and message in err, err


def test_an_unknown_object_in_a_query_is_located_and_kb_validate_reports_it(capsys, kb_copy):
    write_tests(kb_copy, "id: mine\ncases:\n  - name: x\n    query: {object: spoon}\n"
                         "    expect: {feasible: true}\n")
    code, _, err = run(capsys, "--kb", str(kb_copy), "kb", "validate")
    assert code == 3 and "tests/mine.yaml:4:" in err and "unknown object 'spoon'" in err


def test_a_test_file_given_as_a_path_outside_the_kb(capsys, tmp_path):
    path = tmp_path / "extra.yaml"
    path.write_text("id: extra\ncases:\n  - name: pen point away\n    query: {object: pen}\n"
                    "    expect: {axes: {tip: {toward_receiver: '>= 100'}}}\n", encoding="utf-8")
    code, out, _ = run(capsys, "kb", "test", str(path))
    assert code == 0 and "PASS" in out and "pen point away" in out and "1 passed" in out
    path.write_text("id: extra\ncases:\n  - name: x\n    query: {object: pen, task: write}\n"
                    "    expect: {feasible: true}\n", encoding="utf-8")
    code, _, err = run(capsys, "kb", "test", str(path))
    assert code == 3 and f"{path}:4:" in err and "has no task 'write'" in err
    code, _, err = run(capsys, "kb", "test", str(tmp_path / "missing.yaml"))
    assert code == 2 and "does not exist" in err


def test_coverage_lists_every_rule_of_every_culture_with_counts(capsys):
    code, out, _ = run(capsys, "kb", "test", "--coverage", "--json")
    report = json.loads(out)
    assert code == 0
    kb = load_kb()
    every = {r.id: str(r.source) for c in kb.cultures.values() for r in c.rules}
    assert {k: v["source"] for k, v in report["coverage"].items()} == every
    cov = report["coverage"]
    # the Korean elder's two hands applied and decided the mode; the common safety rules
    # rejected candidates
    assert cov["two_hands_for_elders"]["applied"] >= 1
    assert cov["two_hands_for_elders"]["decided"] >= 1
    assert cov["giver_avoids_sharp"]["rejected"] >= 1
    for entry in cov.values():
        assert entry["applied"] >= entry["rejected"] and entry["applied"] >= entry["decided"]
    assert report["never_applied"] == [k for k, v in cov.items() if v["applied"] == 0]
    rule_tags = {t for c in kb.cultures.values() for r in c.rules
                 for t in (*r.applies.object_tags_any, *getattr(r, "forbid_tags", ()),
                           *getattr(r, "require_tags", ()))}
    assert "sharp" not in report["unread_tags"] and "paper" in report["unread_tags"]
    assert not rule_tags & set(report["unread_tags"])
    code, out, _ = run(capsys, "kb", "test", "--coverage", "-k", "korean")
    assert code == 0 and "rule coverage" in out and "never applied:" in out
    assert "tags no rule reads:" in out and "two_hands_for_elders" in out


def test_compare_mug_across_cultures_and_receivers_names_the_korean_rule(capsys):
    kb = load_kb()
    rule = next(r for r in kb.culture("korean").rules if r.id == "two_hands_for_elders")
    source = str(rule.source)
    assert source.startswith("etiquette/korean.yaml:")
    code, out, _ = run(capsys, "compare", "mug", "--culture", "common,korean",
                       "--receiver", "adult,elder")
    assert code == 0
    assert "H1G1" in out and "H2G1" in out
    assert "common/adult -> korean/elder: mode H1G1 -> H2G1" in out
    line = next(x for x in out.splitlines() if "decided" in x and "two_hands_for_elders" in x)
    assert source in line
    code, out, _ = run(capsys, "compare", "mug", "--culture", "common,korean",
                       "--receiver", "adult,elder", "--json")
    report = json.loads(out)
    modes = {(c["culture"], c["receiver"]): c["mode"] for c in report["combinations"]}
    assert modes == {("common", "adult"): "H1G1", ("common", "elder"): "H1G1",
                     ("korean", "adult"): "H1G1", ("korean", "elder"): "H2G1"}
    elder = report["diffs"][-1]
    assert (elder["from"], elder["to"], elder["mode"]) == (
        "common/adult", "korean/elder", ["H1G1", "H2G1"])
    assert elder["decided"][0] == {"rule": "two_hands_for_elders", "source": source,
                                   "culture": "korean", "how": "chose H2G1", "side": "to"}
    assert any(e["rule"] == "two_hands_for_elders" for e in elder["became_active"])
    # common/adult -> common/elder: no etiquette rule changes anything; only where the object
    # is offered and how far the receiver's hand is from the gripper are scored differently
    # (an elder is shorter, with a weaker grip: kb/receivers/elder.yaml).
    same = report["diffs"][0]
    placing = {r.id for r in kb.culture("common").rules if r.kind in ("location", "clearance")}
    assert same["mode"] == ["H1G1", "H1G1"]
    assert {e["rule"] for e in same["decided"]} <= placing
    korean = next(c for c in report["combinations"] if c["receiver"] == "elder"
                  and c["culture"] == "korean")
    assert korean["receiver_parts"] == ["handle"] and korean["axes"]["up"]["toward"] == "up"
    assert {g["hand"] for g in korean["robot_grasps"]} == {"left", "right"}


def test_compare_tasks_shows_the_hammer_turned_over(capsys):
    code, out, _ = run(capsys, "compare", "hammer", "--task", "drive_nail,pull_nail", "--json")
    report = json.loads(out)
    assert code == 0
    drive, pull = report["combinations"]
    assert drive["axes"]["strike"]["toward"] == "down" and pull["axes"]["claw"]["toward"] == "down"
    (diff,) = report["diffs"]
    assert (diff["from"], diff["to"]) == ("drive_nail", "pull_nail")
    assert any(t["rule"] == "task_presentation" for t in diff["thresholds"])
    code, _, err = run(capsys, "compare", "mug", "--culture", "common,klingon")
    assert code == 2 and "unknown culture 'klingon'" in err


def test_a_refusal_is_checked_by_its_reason(capsys, kb_copy):
    """A case can expect the refusing rule in the reason; a wrong text fails, naming both."""
    (kb_copy / "receivers" / "toddler.yaml").write_text(
        "id: toddler\nname: A toddler\nrole: child\nage: 3\nhand: child_hand\n", encoding="utf-8")
    write_tests(kb_copy, """\
id: mine
cases:
  - name: refused, and why
    query: {object: knife, receiver: toddler}
    expect: {outcome: refuse, reason_contains: [no_hazards_to_young_children]}
  - name: refused, but not for the reason written
    query: {object: knife, receiver: toddler}
    expect: {outcome: refuse, reason_contains: [too heavy]}
""")
    code, out, _ = run(capsys, "kb", "test", str(kb_copy / "tests"), "--kb", str(kb_copy),
                       "--json")
    report = json.loads(out)
    assert code == 1
    right, wrong = report["cases"]
    assert right["passed"] and not wrong["passed"]
    (failure,) = wrong["failures"]
    assert failure["expected"] == "too heavy" and "no_hazards_to_young_children" in failure["got"]
