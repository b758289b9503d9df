"""Queue items without a window (ADR 0382): parameters named as a campaign names them, sweep
values, the queue file written and read back, an unreadable one set aside, and the states
a window that went away left behind."""

import json

import pytest

from gelrig.gui.queue_items import (
    COMPLETED,
    QUEUED,
    REHEARSING,
    RUNNING,
    STOPPED,
    QueueItem,
    load_queue,
    save_queue,
    set_param,
    split_values,
    sweep,
)
from gelrig.instrument.core.errors import ConfigError


def table():
    return {"step": [{"kind": "compression_contact_search"},
                     {"kind": "ramp_hold", "name": "hold it", "hold": "20 s"}]}


def test_a_parameter_is_named_by_index_or_step_name():
    raw = table()
    set_param(raw, "step[1].hold", "30 s", "p.toml")
    assert raw["step"][1]["hold"] == "30 s"
    set_param(raw, "hold it.strain", 0.02, "p.toml")
    assert raw["step"][1]["strain"] == 0.02
    for bad in ("step[2].hold", "hold", "nobody.hold", "step[1]."):
        with pytest.raises(ConfigError) as caught:
            set_param(table(), bad, 1, "p.toml")
        assert caught.value.field == "parameter" and "step[0], step[1]" in str(caught.value)


def test_sweep_values_split_on_semicolons_or_top_level_commas():
    assert split_values("10 s; 20 s, 30 s") == ["10 s", "20 s, 30 s"]
    assert split_values("[0.02, 0.04], [0.1]") == ["[0.02, 0.04]", "[0.1]"]
    assert split_values(" 1 ,2,, ") == ["1", "2"]
    items = sweep(QueueItem("p.toml", {"step[0].start": "5 mm"}), "step[1].hold",
                  ["1 s", "2 s"])
    assert [i.params for i in items] == [{"step[0].start": "5 mm", "step[1].hold": "1 s"},
                                         {"step[0].start": "5 mm", "step[1].hold": "2 s"}]


def test_the_queue_file_round_trips_and_left_states_are_settled(tmp_path):
    path = tmp_path / "q.json"
    items = [QueueItem("a.toml", state=state) for state in
             (QUEUED, REHEARSING, RUNNING, COMPLETED, STOPPED)]
    save_queue(path, items)
    assert json.loads(path.read_text())["version"] == 1
    loaded, warning = load_queue(path)
    assert warning == ""
    assert [i.state for i in loaded] == [QUEUED, QUEUED, STOPPED, COMPLETED, STOPPED]
    assert loaded[2].reason == "the window closed while it ran"
    assert load_queue(tmp_path / "none.json") == ([], "")


@pytest.mark.parametrize("text", ["[]", '{"version": 2, "items": []}', "{",
                                  '{"version": 1, "items": [{"path": "a", "colour": 1}]}',
                                  '{"version": 1, "items": [{"path": 3}]}'])
def test_an_unreadable_queue_file_is_set_aside_with_one_line(tmp_path, text):
    path = tmp_path / "q.json"
    path.write_text(text)
    items, warning = load_queue(path)
    assert items == [] and not path.exists()
    aside = list(tmp_path.glob("q.json.corrupt-*"))
    assert len(aside) == 1 and aside[0].read_text() == text
    assert warning.splitlines() == [warning] and aside[0].name in warning
