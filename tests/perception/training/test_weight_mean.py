"""`ld3 ld average`: the element-wise mean of LaneNet checkpoints of one shape."""

import pytest
import torch

from testbed.errors import UserError
from testbed.perception.detectors.neural import LaneNet, load_model
from testbed.perception.training.train import save_checkpoint
from testbed.perception.training.weight_mean import mean_checkpoint


def _checkpoint(path, seed, width=8):
    torch.manual_seed(seed)
    model = LaneNet(width)
    for name, buf in model.named_buffers():
        if name.endswith("num_batches_tracked"):
            buf.fill_(seed)
        elif buf.is_floating_point():
            buf.uniform_(0.5, 1.5)  # running statistics averaged like the weights
    save_checkpoint(model, path, [{"epoch": seed}])
    return model.state_dict()


def test_the_mean_of_two_checkpoints_averages_every_float_tensor_and_keeps_the_firsts_counts(tmp_path):
    a, b = _checkpoint(tmp_path / "a.pt", 1), _checkpoint(tmp_path / "b.pt", 2)
    mean_checkpoint([tmp_path / "a.pt", tmp_path / "b.pt"], tmp_path / "soups" / "m.pt")
    m = load_model(tmp_path / "soups" / "m.pt").state_dict()
    assert m.keys() == a.keys() and any(not v.is_floating_point() for v in m.values())
    for k, v in m.items():
        expected = (a[k] + b[k]) / 2 if v.is_floating_point() else a[k]
        assert torch.equal(v, expected), k
    assert not torch.equal(m["features.0.0.weight"], a["features.0.0.weight"])


def test_checkpoints_of_other_shapes_or_too_few_are_refused_before_writing(tmp_path):
    _checkpoint(tmp_path / "a.pt", 1)
    _checkpoint(tmp_path / "wide.pt", 2, width=16)
    with pytest.raises(UserError, match="another network shape"):
        mean_checkpoint([tmp_path / "a.pt", tmp_path / "wide.pt"], tmp_path / "m.pt")
    with pytest.raises(UserError, match="at least two"):
        mean_checkpoint([tmp_path / "a.pt"], tmp_path / "m.pt")
    assert not (tmp_path / "m.pt").exists()
