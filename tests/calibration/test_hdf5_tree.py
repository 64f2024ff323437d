"""The HDF5 tree of a saved calibration holds exactly the JSON document (property test)."""

from __future__ import annotations

import json

from hypothesis import given, settings, strategies as st

from senscal.persist.hdf5 import read_tree, write_tree

_text = st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"), max_size=8)
_scalar = st.one_of(st.none(), st.booleans(), st.integers(-2**62, 2**62),
                    st.floats(allow_nan=False, allow_infinity=False), _text)
_doc = st.recursive(_scalar, lambda kids: st.one_of(st.lists(kids, max_size=4),
                                                    st.dictionaries(_text, kids, max_size=4)), max_leaves=20)


@settings(max_examples=60, deadline=None)
@given(doc=st.dictionaries(_text, _doc, max_size=6))
def test_json_documents_round_trip_through_hdf5(doc, tmp_path_factory):
    p = tmp_path_factory.mktemp("h5") / "doc.h5"
    write_tree(p, doc)
    back = read_tree(p)
    # Compared as JSON: the document a loader sees (a number list may come back as floats: 1 == 1.0).
    assert json.loads(json.dumps(back)) == json.loads(json.dumps(doc))
