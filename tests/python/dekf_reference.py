"""An independent implementation of docs/model-format.md in NumPy.

Usage: dekf_reference.py MODEL.safetensors REPLAY.mcap

Loads the model file (with the architecture its metadata describes; the
thesis's when it says none), reads /tactile/derivative and /estimate/dekf from
a session written by `slidetrack replay`, runs the filter of the document on
the recorded measurements and prints JSON with the largest relative
differences between its estimates and the recorded ones.
"""
import json
import struct
import sys

import numpy as np
from mcap.reader import make_reader


def load_safetensors(path):
    with open(path, "rb") as f:
        raw = f.read()
    (n,) = struct.unpack("<Q", raw[:8])
    header = json.loads(raw[8 : 8 + n])
    data = raw[8 + n :]
    meta = header.pop("__metadata__", {})
    tensors = {}
    for name, info in header.items():
        assert info["dtype"] == "F32", name
        start, end = info["data_offsets"]
        tensors[name] = np.frombuffer(data[start:end], dtype="<f4").reshape(info["shape"]).astype(np.float32)
    return tensors, meta


# The networks' architecture (docs/model-format.md, "Architecture"): a file
# without the key has the thesis's.
ARCHITECTURE_KEY = "slidetrack.dekf.architecture"
THESIS_ARCHITECTURE = {"width": 64, "residual_blocks": 3, "activation": "relu"}

GELU_C = np.float32(np.sqrt(2.0 / np.pi))
GELU_K = np.float32(0.044715)


def _relu(z):
    mask = (z > 0).astype(np.float32)
    return z * mask, mask


def _tanh(z):
    a = np.tanh(z)
    return a, np.float32(1.0) - a * a


def _gelu(z):
    t = np.tanh(GELU_C * (z + GELU_K * z * z * z))
    half = np.float32(0.5)
    slope = half * (np.float32(1.0) + t) + half * z * (np.float32(1.0) - t * t) * GELU_C * (
        np.float32(1.0) + np.float32(3.0) * GELU_K * z * z
    )
    return half * z * (np.float32(1.0) + t), slope


# activation(z) -> (value, slope), elementwise, float32.
ACTIVATIONS = {"relu": _relu, "tanh": _tanh, "gelu": _gelu}


class Net:
    """One residual MLP; forward() returns the value and the Jacobian row."""

    def __init__(self, t, prefix, arch):
        def lin(name):
            w, b = t[f"{prefix}.{name}.weight"], t[f"{prefix}.{name}.bias"]
            return w, b

        self.act = ACTIVATIONS[arch["activation"]]
        self.enc = lin("encoder.linear")
        assert self.enc[0].shape[0] == arch["width"], (prefix, self.enc[0].shape)
        self.enc_res = (lin("encoder.residual.fc1"), lin("encoder.residual.fc2"))
        self.shared = lin("shared.linear")
        blocks = arch["residual_blocks"]
        self.res = [(lin(f"shared.residual.{k}.fc1"), lin(f"shared.residual.{k}.fc2")) for k in range(blocks)]
        assert f"{prefix}.shared.residual.{blocks}.fc1.weight" not in t, "more blocks than the metadata says"
        self.out = lin("shared.out")

    @staticmethod
    def _linear(layer, h, dh):
        w, b = layer
        return w @ h + b, (w @ dh if dh is not None else None)

    def _activation(self, z, dz):
        a, slope = self.act(z)
        return a, (dz * slope[:, None] if dz is not None else None)

    def _block(self, block, h, dh):
        a, da = self._activation(*self._linear(block[0], h, dh))
        s, ds = self._linear(block[1], a, da)
        return self._activation(s + h, ds + dh if ds is not None else None)

    def forward(self, x, jacobian):
        x = np.asarray(x, dtype=np.float32)
        dx = np.eye(len(x), dtype=np.float32) if jacobian else None
        h, dh = self._activation(*self._linear(self.enc, x, dx))
        h, dh = self._block(self.enc_res, h, dh)
        h, dh = self._linear(self.shared, h, dh)
        for block in self.res:
            h, dh = self._block(block, h, dh)
        y, dy = self._linear(self.out, h, dh)
        return float(y[0]), (dy[0].astype(np.float64) if jacobian else None)


def main():
    model_path, replay_path = sys.argv[1], sys.argv[2]
    t, meta = load_safetensors(model_path)
    m = json.loads(meta["slidetrack.dekf"])
    arch = json.loads(meta[ARCHITECTURE_KEY]) if ARCHITECTURE_KEY in meta else THESIS_ARCHITECTURE
    nn1, nn2, nn3 = (Net(t, name, arch) for name in ("motion", "measurement", "feature"))
    mean_in, std_in = t["feature.input_mean"], t["feature.input_std"]
    lq = t["process_noise.cholesky"].astype(np.float64)
    lq = np.tril(lq)
    Q = lq @ lq.T
    R = float(t["measurement_noise.cholesky"][0, 0]) ** 2
    dt = m["dt_s"]

    derivative, recorded = {}, []
    with open(replay_path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(topics=["/tactile/derivative", "/estimate/dekf"]):
            payload = json.loads(message.data)
            if channel.topic == "/tactile/derivative":
                derivative[message.log_time] = np.array(payload["values"], dtype=np.float64)
            else:
                recorded.append((message.log_time, payload))

    mu = np.zeros(2)
    P = np.diag(m["p0_diag"]).astype(np.float64)
    worst = {"position": 0.0, "velocity": 0.0, "covariance": 0.0}
    for k, (time, est) in enumerate(recorded):
        if k > 0:
            a, J1 = nn1.forward(mu, True)
            F = np.array([[1.0, dt], [J1[0], 1.0 + J1[1]]])
            mu = np.array([mu[0] + mu[1] * dt, mu[1] + a])
            P = F @ P @ F.T + Q
            meas = derivative[time]
            if np.all(np.isfinite(meas)):
                z, _ = nn3.forward(((meas.astype(np.float32) - mean_in) / std_in), False)
                zhat, H = nn2.forward(mu, True)
                S = H @ P @ H + R
                if S > 1e-12:
                    K = P @ H / S
                    mu = mu + K * (z - zhat)
                    A = np.eye(2) - np.outer(K, H)
                    P = A @ P @ A.T + R * np.outer(K, K)
        got = np.array([est["position"], est["velocity"]]) * 100.0
        cov = np.array(est["covariance"]) * 1e4
        # Relative to the value, or to 0.01 (cm, cm/s) near zero: the networks
        # run in float32, whose roundings are ~1e-7 cm/s there.
        rel = lambda a, b: abs(a - b) / max(abs(b), 1e-2)
        worst["position"] = max(worst["position"], rel(mu[0], got[0]))
        worst["velocity"] = max(worst["velocity"], rel(mu[1], got[1]))
        # The covariance against its largest element: an off-diagonal element
        # near zero carries float32 roundings of the diagonal's scale.
        scale = max(float(np.max(np.abs(cov))), 1e-3)
        worst["covariance"] = max(worst["covariance"], float(np.max(np.abs(P - cov))) / scale)
    print(json.dumps({"steps": len(recorded), "architecture": arch, "max_relative_difference": worst}))


if __name__ == "__main__":
    main()
