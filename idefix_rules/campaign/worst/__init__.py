"""The worst case of each chain: a search of the campaign's uncertainty for the worlds of highest
run risk, and the failure boundary around the nominal world (docs/worst-case.md)."""
