"""An independent implementation of docs/model-format.md in NumPy.

Usage: dekf_reference.py MODEL.safetensors REPLAY.mcap
       dekf_reference.py --check-golden tests/golden/dekf.json

Loads the model file (with the architecture and the state its metadata
describes; the thesis's when it says none), reads /tactile/derivative and the
estimates (/estimate/dekf of a sliding model, /estimate/dekf_planar of a
planar one) from a session written by `slidetrack replay`, runs the filter of
the document on the recorded measurements and prints JSON with the largest
relative differences between its estimates and the recorded ones.

With --check-golden it runs the same networks and filter on the golden
file's models and inputs (tests/golden/, docs/model-format.md "The golden
file") and prints JSON with the largest differences from its outputs.
"""
import json
import os
import struct
import sys

import numpy as np


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
    """One residual MLP; forward() returns the output vector and its Jacobian."""

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
        return y.astype(np.float64), (dy.astype(np.float64) if jacobian else None)


DEG = 180.0 / np.pi
# The state's units from the SI units of the recorded estimates.
FROM_SI = {"sliding": [100.0, 100.0], "planar": [1000.0, 1000.0, DEG, 1000.0, 1000.0, DEG]}
ESTIMATE_TOPIC = {"sliding": "/estimate/dekf", "planar": "/estimate/dekf_planar"}


def recorded_state(state, payload):
    """The recorded estimate in SI units: mean and covariance."""
    if state == "sliding":
        return np.array([payload["position"], payload["velocity"]]), np.array(payload["covariance"])
    s = payload["state"]
    mean = np.array(
        s["translation_m"] + [s["rotation_rad"]] + s["velocity_m_per_s"] + [s["angular_velocity_rad_per_s"]]
    )
    return mean, np.array(payload["covariance"]).reshape(6, 6)


class Model:
    """A model file: its three networks, normalisation, noise and filter."""

    def __init__(self, path):
        t, meta = load_safetensors(path)
        self.meta = json.loads(meta["slidetrack.dekf"])
        self.arch = json.loads(meta[ARCHITECTURE_KEY]) if ARCHITECTURE_KEY in meta else THESIS_ARCHITECTURE
        self.nets = {name: Net(t, name, self.arch) for name in ("motion", "measurement", "feature")}
        self.mean_in, self.std_in = t["feature.input_mean"], t["feature.input_std"]
        self.state = self.meta.get("state", "sliding")
        self.d = 1 if self.state == "sliding" else 3
        self.n = 2 * self.d
        lq = np.tril(t["process_noise.cholesky"].astype(np.float64))
        self.Q = lq @ lq.T
        lr = np.tril(t["measurement_noise.cholesky"].astype(np.float64))
        self.R = lr @ lr.T
        self.dt = self.meta["dt_s"]

    def initial(self):
        """mu0 and P0."""
        return np.zeros(self.n), np.diag(self.meta["p0_diag"]).astype(np.float64)

    def step(self, mu, P, meas):
        """One filter step (docs/model-format.md, "The filter") with the
        unnormalised measurement `meas`; returns (mu, P, corrected)."""
        n, d, dt = self.n, self.d, self.dt
        a, J1 = self.nets["motion"].forward(mu, True)
        F = np.eye(n)
        F[:d, d:] = dt * np.eye(d)
        F[d:, :] += J1
        mu = np.concatenate([mu[:d] + mu[d:] * dt, mu[d:] + a])
        P = F @ P @ F.T + self.Q
        if not np.all(np.isfinite(meas)):
            return mu, P, False
        z, _ = self.nets["feature"].forward(((meas.astype(np.float32) - self.mean_in) / self.std_in), False)
        zhat, H = self.nets["measurement"].forward(mu, True)
        S = H @ P @ H.T + self.R
        if not np.all(np.linalg.eigvalsh(S) > 1e-12):
            return mu, P, False
        K = P @ H.T @ np.linalg.inv(S)
        mu = mu + K @ (z - zhat)
        A = np.eye(n) - K @ H
        return mu, A @ P @ A.T + K @ self.R @ K.T, True


def worst(got, want, floor):
    """The largest |got - want| / max(|want|, floor)."""
    got, want = np.asarray(got, dtype=np.float64).ravel(), np.asarray(want, dtype=np.float64).ravel()
    assert got.shape == want.shape, (got.shape, want.shape)
    return float(np.max(np.abs(got - want) / np.maximum(np.abs(want), floor)))


def check_golden(path):
    """Runs the networks and the filter on every model of the golden file;
    prints the largest differences (relative to max(|expected|, 1); the
    covariance to its largest element)."""
    golden = json.load(open(path))
    report = []
    for entry in golden["models"]:
        model = Model(os.path.join(os.path.dirname(path), entry["file"]))
        assert model.arch == entry["architecture"], (model.arch, entry["architecture"])
        network = 0.0
        for name, probes in entry["networks"].items():
            for probe in probes:
                jacobian = "jacobian" in probe
                y, J = model.nets[name].forward(probe["input"], jacobian)
                network = max(network, worst(y, probe["output"], 1.0))
                if jacobian:
                    network = max(network, worst(J, probe["jacobian"], 1.0))
        f = entry["filter"]
        mu, P = model.initial()
        mean = cov = 0.0
        corrected = []
        for k, meas in enumerate(f["measurements"]):
            meas = np.array([np.nan if v is None else v for v in meas], dtype=np.float64)
            mu, P, ok = model.step(mu, P, meas)
            corrected.append(ok)
            mean = max(mean, worst(mu, f["mean"][k], 1.0))
            want = np.array(f["cov"][k])
            cov = max(cov, worst(P, want, float(np.max(np.abs(want)))))
        report.append(
            {
                "name": entry["name"],
                "network": network,
                "mean": mean,
                "covariance": cov,
                "corrected_as_golden": corrected == f["corrected"],
            }
        )
    print(json.dumps({"models": report}))


def main():
    if sys.argv[1] == "--check-golden":
        check_golden(sys.argv[2])
        return
    from mcap.reader import make_reader

    model_path, replay_path = sys.argv[1], sys.argv[2]
    model = Model(model_path)
    state, d = model.state, model.d
    topic = ESTIMATE_TOPIC[state]

    derivative, recorded = {}, []
    with open(replay_path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(topics=["/tactile/derivative", topic]):
            payload = json.loads(message.data)
            if channel.topic == "/tactile/derivative":
                derivative[message.log_time] = np.array(payload["values"], dtype=np.float64)
            else:
                recorded.append((message.log_time, payload))

    scale = np.array(FROM_SI[state])
    mu, P = model.initial()
    worst_rel = {"position": 0.0, "velocity": 0.0, "covariance": 0.0}
    for k, (time, est) in enumerate(recorded):
        if k > 0:
            mu, P, _ = model.step(mu, P, derivative[time])
        got_si, cov_si = recorded_state(state, est)
        got = got_si * scale
        cov = cov_si * np.outer(scale, scale)
        # Relative to the value, or to 0.01 (cm, cm/s; mm, deg) near zero: the
        # networks run in float32, whose roundings are ~1e-7 there.
        rel = lambda a, b: abs(a - b) / max(abs(b), 1e-2)
        worst_rel["position"] = max([worst_rel["position"]] + [rel(mu[i], got[i]) for i in range(d)])
        worst_rel["velocity"] = max([worst_rel["velocity"]] + [rel(mu[d + i], got[d + i]) for i in range(d)])
        # The covariance against its largest element: an off-diagonal element
        # near zero carries float32 roundings of the diagonal's scale.
        c_scale = max(float(np.max(np.abs(cov))), 1e-3)
        worst_rel["covariance"] = max(worst_rel["covariance"], float(np.max(np.abs(P - cov))) / c_scale)
    out = {"steps": len(recorded), "architecture": model.arch, "state": state, "max_relative_difference": worst_rel}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
