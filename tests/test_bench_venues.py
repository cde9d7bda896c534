"""bench/venues.py, the benchmarks' venue and answer caches."""

from omninav.presets import resolve


def test_the_benches_keep_the_answers_of_each_search_apart():
    """bench/venues.py caches a venue's answers under a name that says how its clips were
    searched: the answers of the search before the shortlist keep their names (and their figures),
    and the shortlist's are not read for them, nor they for it."""
    from bench.venues import SEARCH_KEYS, search_tag

    assert "shortlist" in SEARCH_KEYS  # a --set shortlist reaches the search, not a new venue
    conf = resolve("default")
    assert search_tag(conf) == "-shared-sl32"
    assert search_tag({**conf, "shortlist": 16}) == search_tag({**conf, "shortlist": 8}) == "-shared"
    assert search_tag(resolve("paper")) == ""
