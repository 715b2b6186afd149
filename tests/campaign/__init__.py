"""The randomized campaign over recording shapes (issue 43): shapes drawn by ``hypothesis``,
recordings of them from the independent twin (``scripts/independent_twin.py``), and the
invariants every recording must keep (``tests/test_campaign.py``, ``scripts/campaign.py``)."""
