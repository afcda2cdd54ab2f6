"""Model trees: built-ins, TOML round trip, validation errors (thesis §12.2, §12.3)."""
import math

import pytest

import topopose as tp
from topopose.errors import InputError
from topopose.pose.model import BUILTIN, load_model


@pytest.mark.parametrize("name", BUILTIN)
def test_builtins_load_and_round_trip(name, tmp_path):
    m = load_model(name)
    assert m.name == name
    assert m.threshold is not None and 0 < m.threshold <= 2
    p = tmp_path / f"{name}.toml"
    m.save(p)
    m2 = load_model(p)
    assert m2.parts == m.parts and m2.root == m.root and m2.complete == m.complete
    assert m2.tree.edges == m.tree.edges
    assert m2.constraints == m.constraints and m2.threshold == m.threshold
    # the alignment input: finite weights sum to 1, rooted as §12.1.1 says
    pat = m.pattern()
    assert math.isclose(pat.total_weight(), 1.0)
    assert pat.root == m.root


def test_contract_part_names_and_rooting():
    h = load_model("human")
    assert set(h.parts) == {"head", "torso", "crotch", "hand_1", "hand_2", "foot_1", "foot_2"}
    assert h.complete and h.root == "torso"            # highest degree part
    assert {(c.kind, c.parts) for c in h.constraints} == {("above", ("head", "torso")),
                                                          ("above", ("torso", "crotch")),
                                                          ("above", ("crotch", "foot_1")),
                                                          ("above", ("crotch", "foot_2"))}
    assert sorted(map(sorted, h.interchangeable())) == [["foot_1", "foot_2"], ["hand_1", "hand_2"]]
    assert load_model("human", constraints=False).constraints == []
    hand = load_model("hand")
    assert not hand.complete and hand.root == "arm" and hand.infinite_edge == ("arm", "palm")
    (b,) = hand.constraints
    assert b.kind == "between" and b.relation == "b"
    assert b.parts == ("thumb", "index", "middle", "ring", "little")
    # acrobatics switch keeps betweenness
    assert load_model("hand", constraints=False).constraints == hand.constraints
    dog = load_model("dog")
    assert sorted(map(sorted, dog.interchangeable())) == [["paw_1", "paw_2"], ["paw_3", "paw_4"]]
    spider = load_model("spider")
    assert spider.root == "cephalothorax" and len(spider.interchangeable()[0]) == 8
    assert tp.load_model is load_model


GOOD = """
[model]
name = "x"
complete = true
[[edge]]
parts = ["a", "b"]
length = 1
[[edge]]
parts = ["b", "c"]
length = 2
"""


def _write(tmp_path, text):
    p = tmp_path / "m.toml"
    p.write_text(text)
    return p


def test_default_root_is_highest_degree(tmp_path):
    m = load_model(_write(tmp_path, GOOD))
    assert m.root == "b"


@pytest.mark.parametrize("extra, words", [
    ('[[edge]]\nparts = ["c", "a"]\nlength = 1\n', "cycle"),
    ('[[edge]]\nparts = ["b", "a"]\nlength = 1\n', "duplicate edge"),
    ('[[constraint]]\nkind = "above"\nparts = ["a", "c"]\n', "not adjacent"),
    ('[[constraint]]\nkind = "above"\nparts = ["a", "zz"]\n', "unknown part 'zz'"),
    ('[[constraint]]\nkind = "abve"\nparts = ["a", "b"]\n', "kind 'abve'"),
    ('[[constraint]]\nkind = "between"\nparts = ["a", "b"]\n', "at least 3"),
    ('[[constraint]]\nkind = "between"\nparts = ["a", "b", "c"]\nrelation = "q"\n', "relation"),
    ('[[constraint]]\nkind = "above"\nparts = ["a", "b"]\naxis = "+w"\n', "axis"),
    ('[[edge]]\nparts = ["c", "d"]\nlenght = 1\n', "lenght"),
    ('[[edge]]\nparts = ["c", "d"]\nlength = -1\n', "length"),
    ('[[edge]]\nparts = ["c", "d"]\nlength = "long"\n', "length"),
    ('[[edge]]\nparts = ["c", "d"]\nlength = "inf"\n', "complete = true"),
])
def test_validation_errors_name_file_and_field(tmp_path, extra, words):
    p = _write(tmp_path, GOOD + extra)
    with pytest.raises(InputError) as e:
        load_model(p)
    assert str(p) in str(e.value) and words in str(e.value)


def test_incomplete_model_rules(tmp_path):
    base = GOOD.replace("complete = true", "complete = false")
    with pytest.raises(InputError, match="needs one edge of length"):
        load_model(_write(tmp_path, base))
    two = base + '[[edge]]\nparts = ["c", "d"]\nlength = "inf"\n[[edge]]\nparts = ["a", "e"]\nlength = "inf"\n'
    with pytest.raises(InputError, match="both infinite"):
        load_model(_write(tmp_path, two))
    inner = base.replace('length = 2', 'length = "inf"') + '[[edge]]\nparts = ["c", "d"]\nlength = 1\n'
    with pytest.raises(InputError, match="must end at a part"):
        load_model(_write(tmp_path, inner))
    ok = load_model(_write(tmp_path, base + '[[edge]]\nparts = ["c", "d"]\nlength = "inf"\n'))
    assert ok.root == "d" and ok.infinite_edge == ("d", "c")
    assert math.isclose(ok.pattern().total_weight(), 1.0)


def test_declared_parts_catch_typos(tmp_path):
    text = GOOD.replace('name = "x"', 'name = "x"\nparts = ["a", "b", "c"]').replace('["b", "c"]', '["b", "cc"]')
    with pytest.raises(InputError, match="unknown part 'cc'"):
        load_model(_write(tmp_path, text))
    dup = GOOD.replace('name = "x"', 'name = "x"\nparts = ["a", "b", "b", "c"]')
    with pytest.raises(InputError, match="twice"):
        load_model(_write(tmp_path, dup))


def test_bad_files(tmp_path):
    with pytest.raises(InputError, match="not a built-in"):
        load_model("humna")
    with pytest.raises(InputError, match="not valid TOML"):
        load_model(_write(tmp_path, "[model\nname="))
    with pytest.raises(InputError, match=r"unknown field\(s\) \['complet'\]"):
        load_model(_write(tmp_path, GOOD.replace("complete", "complet")))
    with pytest.raises(InputError, match="no \\[\\[edge\\]\\]"):
        load_model(_write(tmp_path, '[model]\nname = "x"\n'))
