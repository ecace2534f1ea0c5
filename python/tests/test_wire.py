"""polycal.AcWire and polycal.TableWire: the library's wire rules (docs/FORMAT.md §7.7)
told scripted events from Python, decided as tests/lab/wire_rules.rs has the library
decide them."""

import pytest

import polycal


def carry_out(wire, replies, pending=None):
    """Carries out `wire`'s actions against a scripted device: `replies(text)` gives the
    lines a command sent produces. Returns (outcome, sent, notes)."""
    pending = list(pending or [])
    sent, notes, now = [], [], 0.0
    while True:
        now += 0.01
        action = wire.poll()
        if action.kind == "done":
            return wire.outcome(), sent, notes
        if action.kind in ("drain", "await_input"):
            lines, pending[:] = list(pending), []
            wire.tell(now, "drained" if action.kind == "drain" else "input", lines=lines)
        elif action.kind == "clear":
            pending.clear()
            wire.tell(now, "cleared")
        elif action.kind == "send":
            sent.append(action.text)
            pending.extend(replies(action.text, sent))
            wire.tell(now, "sent")
        elif action.kind == "read_line":
            wire.tell(now, "line", line=pending.pop(0) if pending else None)
        elif action.kind == "wait":
            now += action.seconds
            wire.tell(now, "waited")
        elif action.kind == "note":
            notes.append((action.event, action.text))


def test_a_stale_line_is_drained_and_a_reply_with_another_behind_it_is_asked_again():
    script = {
        "a\n": [["4 003 1.000000 0.000000", "4 003 2.000000 0.000000"], ["4 003 3.000000 0.500000"]],
        "d\n": [["4 003 2.500000 0.000000", "8 ELCOMAT 3000 S/N 1"]],
    }

    def replies(text, sent):
        return script[text].pop(0)

    ac = polycal.AcWire("lab:ac1", "elcomat3000", reply_timeout=0.1)
    ac.begin("measure")
    outcome, sent, notes = carry_out(ac, replies, pending=["4 003 9.000000 0.000000"])
    assert outcome == (3, 3.0, 0.5)
    assert sent == ["a\n", "d\n", "a\n"]
    assert notes == [("discarded", "4 003 2.500000 0.000000")]


def test_an_unreferenced_pi_axis_is_referenced_before_its_first_move():
    # A C-863 whose axis is not referenced (FRF? 1 → 1=0): the start references it (FRF 1),
    # the move goes once and the position is read back.
    referenced = {"done": False}

    def replies(text, sent):
        if text == "FRF 1\n":
            referenced["done"] = True
            return []
        return {
            "ERR?\n": ["0"],
            "ONT? 1\n": ["1=1"],
            "FRF? 1\n": ["1=1" if referenced["done"] else "1=0"],
            "*IDN?\n": ["PI C-863"],
            "POS? 1\n": ["1=22.5000"],
        }.get(text, [])

    table = polycal.TableWire("lab:table", "pi-gcs2", reply_timeout=0.1, retries=2)
    table.begin("start")
    outcome, sent, _ = carry_out(table, replies)
    assert outcome is None
    assert "FRF 1\n" in sent
    table.begin("move", 22.5)
    outcome, moves, _ = carry_out(table, replies)
    assert outcome == 22.5
    # `ONT? 1` answers `1=1`, word for word the last reply (`FRF? 1`'s): doubtful, so the
    # controller is brought back in step (`*IDN?`) and asked again before the move.
    assert moves == [
        "ONT? 1\n", "*IDN?\n", "ONT? 1\n", "MOV 1 22.5\n", "ERR?\n", "ONT? 1\n", "POS? 1\n",
    ]
    table.begin("state")
    assert carry_out(table, replies)[0] == "ready"


def test_an_instrument_error_and_a_wrong_event_raise_the_librarys_words():
    ac = polycal.AcWire("lab:ac1", reply_timeout=0.1)
    ac.begin("measure")
    with pytest.raises(polycal.PolycalError, match="no reply to \"a\\\\n\" within 100 ms \\(4 attempts\\)"):
        carry_out(ac, lambda text, sent: [])
    ac.begin("measure")
    assert ac.poll().kind == "drain"
    with pytest.raises(polycal.PolycalError, match="^the wire rules asked for Drain, and were told Sent"):
        ac.tell(0.0, "sent")
    with pytest.raises(polycal.PolycalError, match="a time that is not a finite number"):
        ac.tell(float("nan"), "drained", lines=[])
    with pytest.raises(ValueError, match="op: expected start, identify or measure"):
        ac.begin("read")
    table = polycal.TableWire("lab:table")
    with pytest.raises(ValueError, match="move with a finite deg"):
        table.begin("move", float("inf"))
    with pytest.raises(polycal.PolycalError, match="^no bundled profile \"no-such-make\" and no such file"):
        polycal.TableWire("lab:table", "no-such-make")
