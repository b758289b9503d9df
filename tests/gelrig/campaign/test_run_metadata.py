"""``gelrig campaign --sample/--operator/--note/--tag``: each member's run records them and
the kept runs are found by ``gelrig runs`` (ADR 0370)."""

import dataclasses
import json

from gelrig.campaign.member import run_member
from gelrig.campaign.spec import load_campaign
from gelrig.cli import main
from tests.gelrig.campaign import tiny


def test_a_kept_member_run_records_the_campaigns_metadata(tmp_path, capsys):
    spec = load_campaign(tiny.write(tmp_path, tiny.COMPRESSION, replicates=1))
    meta = {"operator": "ada", "note": "batch 12", "tags": ["camp"], "sample": "gel-C1"}
    member = dataclasses.replace(spec.members[0], keep_dir=str(tmp_path / "runs" / "m0"),
                                 run_meta=meta)
    assert run_member(member)["state"] == "completed"
    recorded = json.loads((tmp_path / "runs" / "m0" / "run.json").read_text())
    assert recorded["sample"]["name"] == "gel-C1"
    assert recorded["sample"]["diameter"] > 0  # the protocol's sphere, renamed
    assert (recorded["operator"], recorded["note"], recorded["tags"]) == ("ada", "batch 12",
                                                                          ["camp"])
    assert main(["runs", str(tmp_path / "runs"), "--json", "--tag", "camp"]) == 0
    [listed] = json.loads(capsys.readouterr().out)
    assert (listed["sample"], listed["status"]) == ("gel-C1", "completed")


def test_a_bad_sample_name_stops_the_campaign_in_one_line(tmp_path, capsys):
    path = tiny.write(tmp_path, tiny.COMPRESSION, replicates=1)
    assert main(["campaign", str(path), "--out", str(tmp_path / "out"),
                 "--sample", "a/b"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--sample" in err[0], err
