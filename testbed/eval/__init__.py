"""Evaluation, in rooms: one run (`run`), campaigns and their backends (`campaign`), the worst-case search
(`search`), the paper's experiments (`experiments`), reports over finished runs (`report`) and analysis tools
(`analysis`)."""
