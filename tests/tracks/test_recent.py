import pickle

from tracks.recent import RecentAnswers


def test_keeps_the_last_answers_and_drops_the_oldest_first():
    memo: RecentAnswers[int, str] = RecentAnswers(2)
    assert memo.keep(1, "a") == "a" and memo.keep(2, "b") == "b"
    memo.keep(3, "c")
    assert dict(memo) == {2: "b", 3: "c"}
    again = pickle.loads(pickle.dumps(memo))
    assert again == memo and again.size == 2
