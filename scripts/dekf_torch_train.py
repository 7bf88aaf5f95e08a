#!/usr/bin/env python3
"""An independent PyTorch implementation of the dEKF's training (thesis
Sec. 2.5.3 and 6.2.4), written from docs/model-format.md and the thesis, to
compare with `slidetrack train`. Needs `torch`, `numpy` and `mcap`
(`scripts/setup.sh --test` installs them into target/pyenv).

    dekf_torch_train.py --train S1.mcap S2.mcap ... --out model.safetensors --seed 1
    slidetrack eval --model model.safetensors TEST.mcap ...
    dekf_torch_train.py --check-golden tests/golden/dekf.json

The last loads the golden file's models (tests/golden/, any architecture)
into this script's own modules and runs its own networks and filter on the
file's inputs, printing the largest differences from the file's outputs;
`cargo test` (tests/dekf_golden.rs) runs it.

It reads labelled sessions (`/tactile/zeroed`, `/ground_truth/sliding`,
`/protocol/events`, the `taxel_layout` channel metadata), makes the
feature network's input with the documented derivative filter, trains the
model of docs/model-format.md by backpropagation through time with PyTorch's
defaults (nn.Linear's initialisation, Adam, the mean squared error of
eq. 2.149, no clipping), and writes the documented model file, so that
`slidetrack eval` scores it exactly as it scores its own models.

Everything here is plain PyTorch autograd: the Jacobians of NN1 and NN2
come from forward-mode tangents carried through the network (each scaled
by its activation's slope), and autograd differentiates through them.
"""
import argparse
import json
import math
import os
import struct
import sys
import time

import numpy as np
import torch
from torch import nn

FINGERS = ["thumb", "index", "middle"]
GT_TOPIC = "/ground_truth/sliding"


# ---------------------------------------------------------------- data


def derivative_filter(times_s, values, q=2.0e5, r=25.0, p_dd=1.0e4):
    """docs/model-format.md, "The derivative filter": one constant-velocity
    Kalman filter per channel; returns the derivative at every scan."""
    n, c = values.shape
    out = np.zeros((n, c))
    for ch in range(c):
        x = None
        P = None
        last = None
        for k in range(n):
            t, v = times_s[k], values[k, ch]
            dt = 0.0 if last is None else max(t - last, 0.0)
            last = t
            if x is None:
                if np.isfinite(v):
                    x = np.array([v, 0.0])
                    P = np.diag([r, p_dd])
            else:
                F = np.array([[1.0, dt], [0.0, 1.0]])
                Q = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
                x = F @ x
                P = F @ P @ F.T + Q
                if np.isfinite(v):
                    S = P[0, 0] + r
                    K = P[:, 0] / S
                    x = x + K * (v - x[0])
                    A = np.eye(2) - np.outer(K, [1.0, 0.0])
                    P = A @ P @ A.T + r * np.outer(K, K)
            out[k, ch] = 0.0 if x is None else x[1]
    return out


def read_session(path, axes=("x", "y"), rate_hz=30.0):
    """The model inputs and ground truth of one session at the filter rate:
    (measurements [T, C], truth [T, 2] in cm and cm/s relative to the first
    step, tactile rate, decimation)."""
    from mcap.reader import make_reader

    zeroed, truth, release = [], {}, None
    layout = None
    with open(path, "rb") as f:
        reader = make_reader(f)
        for _, channel, message in reader.iter_messages(
            topics=["/tactile/zeroed", GT_TOPIC, "/protocol/events", "/tactile/raw"]
        ):
            if channel.topic == "/tactile/raw":
                if layout is None:
                    layout = json.loads(channel.metadata["taxel_layout"])
                continue
            payload = json.loads(message.data)
            if channel.topic == "/tactile/zeroed":
                zeroed.append((message.log_time, payload["sensors"]))
            elif channel.topic == GT_TOPIC:
                truth[message.log_time] = (payload["position"], payload["velocity"])
            elif release is None and (payload["phase"] == "release" or payload.get("abort")):
                release = message.log_time
    zeroed = [z for z in zeroed if release is None or z[0] < release]
    # Each finger's reading: one taxel of its sensor, or the sensor's mean.
    cols = []
    for finger in FINGERS:
        spec = layout["fingers"][finger]
        for axis in axes:
            cols.append((spec["sensor"], spec.get("taxel"), axis))
    values = np.zeros((len(zeroed), len(cols)))
    for k, (_, sensors) in enumerate(zeroed):
        by_name = {s["name"]: s["taxels"] for s in sensors}
        for c, (sensor, taxel, axis) in enumerate(cols):
            taxels = by_name[sensor]
            if taxel is None:
                values[k, c] = np.mean([t[axis] if t[axis] is not None else np.nan for t in taxels])
            else:
                v = taxels[taxel][axis]
                values[k, c] = np.nan if v is None else v
    times_ns = np.array([z[0] for z in zeroed], dtype=np.int64)
    times_s = times_ns * 1e-9
    rate = (len(times_s) - 1) / (times_s[-1] - times_s[0])
    decimation = max(int(round(rate / rate_hz)), 1)
    deriv = derivative_filter(times_s, values)
    keep = np.arange(0, len(times_s), decimation)
    gt = np.array([truth[int(t)] for t in times_ns[keep]])
    gt[:, 0] -= gt[0, 0]
    return deriv[keep], gt * 100.0, rate, decimation


def load_cached(path, cache_dir, rate_hz):
    os.makedirs(cache_dir, exist_ok=True)
    st = os.stat(path)
    key = os.path.join(cache_dir, f"{os.path.basename(path)}-{st.st_size}-{int(st.st_mtime)}.npz")
    if os.path.exists(key):
        d = np.load(key)
        return d["m"], d["gt"], float(d["rate"]), int(d["dec"])
    m, gt, rate, dec = read_session(path, rate_hz=rate_hz)
    np.savez(key, m=m, gt=gt, rate=rate, dec=dec)
    return m, gt, rate, dec


# ---------------------------------------------------------------- model


class Residual(nn.Module):
    def __init__(self, h=64):
        super().__init__()
        self.fc1 = nn.Linear(h, h)
        self.fc2 = nn.Linear(h, h)


class Encoder(nn.Module):
    def __init__(self, i, h=64):
        super().__init__()
        self.linear = nn.Linear(i, h)
        self.residual = Residual(h)


class Shared(nn.Module):
    def __init__(self, h=64, blocks=3, d=1):
        super().__init__()
        self.linear = nn.Linear(h, h)
        self.residual = nn.ModuleList([Residual(h) for _ in range(blocks)])
        self.out = nn.Linear(h, d)


def lin(layer, X, bias_rows):
    """Linear layer on stacked rows: values first, then tangents; `bias_rows`
    [rows, 1] is 1 on the value rows (bias added) and 0 on the tangents."""
    if bias_rows is None:
        return torch.addmm(layer.bias, X, layer.weight.T)
    return torch.addmm(bias_rows * layer.bias, X, layer.weight.T)


GELU_C = math.sqrt(2.0 / math.pi)
GELU_K = 0.044715


def _gelu_slope(v):
    """The derivative of GELU's tanh approximation."""
    t = torch.tanh(GELU_C * (v + GELU_K * v**3))
    return 0.5 * (1.0 + t) + 0.5 * v * (1.0 - t * t) * GELU_C * (1.0 + 3.0 * GELU_K * v * v)


# docs/model-format.md's activations: (value, slope), both differentiable.
SMOOTH = {
    "tanh": (torch.tanh, lambda v: 1.0 - torch.tanh(v) ** 2),
    "gelu": (lambda v: nn.functional.gelu(v, approximate="tanh"), _gelu_slope),
}


def activate(X, b, activation="relu", extra=None):
    """The activation on stacked rows: the `b` value rows take it, the
    tangent rows are scaled by its slope at the values (ReLU: their mask)."""
    pre = X if extra is None else X + extra
    if activation == "relu":
        if pre.shape[0] == b:
            return torch.relu(pre)
        mask = (pre[:b] > 0).to(X.dtype)
        return pre * mask.repeat(X.shape[0] // b, 1)
    value, slope = SMOOTH[activation]
    if pre.shape[0] == b:
        return value(pre)
    v = pre[:b]
    return torch.cat([value(v), pre[b:] * slope(v).repeat(X.shape[0] // b - 1, 1)])


class Net(nn.Module):
    """docs/model-format.md's network (the thesis's by default); forward()
    with tangents returns the value and the Jacobian with respect to the
    input ([B] and [B, I] for one output, [B, D] and [B, D, I] for D)."""

    def __init__(self, i, h=64, blocks=3, activation="relu", d=1):
        super().__init__()
        self.encoder = Encoder(i, h)
        self.shared = Shared(h, blocks, d)
        self.activation = activation

    def block(self, r, H, b, rows):
        a = activate(lin(r.fc1, H, rows), b, self.activation)
        return activate(lin(r.fc2, a, rows), b, self.activation, extra=H)

    def forward(self, x, jacobian=False):
        b, i = x.shape
        if jacobian:
            # rows: the values, then d/dx_j for each input j
            eye = torch.eye(i, dtype=x.dtype).repeat_interleave(b, 0)
            X = torch.cat([x, eye])
            rows = torch.zeros(X.shape[0], 1, dtype=x.dtype)
            rows[:b] = 1.0
        else:
            X, rows = x, None
        H = activate(lin(self.encoder.linear, X, rows), b, self.activation)
        H = self.block(self.encoder.residual, H, b, rows)
        H = lin(self.shared.linear, H, rows)
        for r in self.shared.residual:
            H = self.block(r, H, b, rows)
        Y = lin(self.shared.out, H, rows)
        d = Y.shape[1]
        if d == 1:
            Y = Y[:, 0]
        if not jacobian:
            return Y
        if d == 1:
            return Y[:b], Y[b:].reshape(i, b).T
        return Y[:b], Y[b:].reshape(i, b, d).permute(1, 2, 0)


THESIS_ARCHITECTURE = {"width": 64, "residual_blocks": 3, "activation": "relu"}


class Dekf(nn.Module):
    """The model of docs/model-format.md: `d` degrees of freedom (1: the
    thesis's sliding state), networks of `arch` (the thesis's by default)."""

    def __init__(self, channels, lq_init, lr_init, arch=None, d=1):
        super().__init__()
        a = arch or THESIS_ARCHITECTURE
        net = lambda i: Net(i, a["width"], a["residual_blocks"], a["activation"], d)
        self.motion = net(2 * d)
        self.measurement = net(2 * d)
        self.feature = net(channels)
        self.register_buffer("input_mean", torch.zeros(channels))
        self.register_buffer("input_std", torch.ones(channels))
        self.lq = nn.Parameter(torch.tensor(lq_init, dtype=torch.float32))
        self.lr = nn.Parameter(torch.tensor(lr_init, dtype=torch.float32))

    def noise(self):
        L = torch.tril(self.lq)
        return L @ L.T, (self.lr @ self.lr.T)[0, 0]


def run_filter(model, mu, P, meas, valid, dt, steps, covariances=None):
    """The dEKF over `steps` steps from (mu, P) [B,2], [B,2,2] with the
    normalised measurements meas [steps, B, C]; returns the corrected means
    [steps, B, 2] (and appends the covariances [B,2,2] to `covariances`
    when it is a list)."""
    Q, R = model.noise()
    out = []
    B = mu.shape[0]
    for k in range(steps):
        a, J1 = model.motion(mu, jacobian=True)
        F = torch.stack(
            [
                torch.stack([torch.ones(B), torch.full((B,), dt)], 1),
                torch.stack([J1[:, 0], 1.0 + J1[:, 1]], 1),
            ],
            1,
        )
        mu = torch.stack([mu[:, 0] + mu[:, 1] * dt, mu[:, 1] + a], 1)
        P = F @ P @ F.transpose(1, 2) + Q
        z = model.feature(meas[k])
        zhat, H = model.measurement(mu, jacobian=True)
        PH = (P @ H.unsqueeze(2))[:, :, 0]
        S = (H * PH).sum(1) + R
        K = PH / S.unsqueeze(1)
        mu_c = mu + K * (z - zhat).unsqueeze(1)
        A = torch.eye(2).expand(B, 2, 2) - K.unsqueeze(2) * H.unsqueeze(1)
        P_c = A @ P @ A.transpose(1, 2) + R * K.unsqueeze(2) * K.unsqueeze(1)
        ok = (valid[k] & (S > 1e-12)).unsqueeze(1)
        mu = torch.where(ok, mu_c, mu)
        P = torch.where(ok.unsqueeze(2), P_c, P)
        out.append(mu)
        if covariances is not None:
            covariances.append(P)
    return torch.stack(out)


# ---------------------------------------------------------------- file


def save(model, path, meta):
    tensors = {}
    for name, t in model.state_dict().items():
        if name == "input_mean":
            name = "feature.input_mean"
        elif name == "input_std":
            name = "feature.input_std"
        elif name == "lq":
            name = "process_noise.cholesky"
            t = torch.tril(t)
        elif name == "lr":
            name = "measurement_noise.cholesky"
        tensors[name] = t.detach().to(torch.float32).contiguous().numpy()
    header = {"__metadata__": {"format": "slidetrack-dekf-1", "slidetrack.dekf": json.dumps(meta)}}
    blobs, offset = [], 0
    for name in sorted(tensors):
        b = tensors[name].astype("<f4").tobytes()
        header[name] = {"dtype": "F32", "shape": list(tensors[name].shape), "data_offsets": [offset, offset + len(b)]}
        blobs.append(b)
        offset += len(b)
    h = json.dumps(header).encode()
    h += b" " * (-len(h) % 8)
    with open(path, "wb") as f:
        f.write(struct.pack("<Q", len(h)) + h + b"".join(blobs))


def load(path):
    """A model file written by slidetrack (docs/model-format.md) as a Dekf
    module, loaded strictly (every tensor named and shaped as this module's
    own), and its metadata."""
    with open(path, "rb") as f:
        raw = f.read()
    (n,) = struct.unpack("<Q", raw[:8])
    header = json.loads(raw[8 : 8 + n])
    data = raw[8 + n :]
    info = header.pop("__metadata__", {})
    meta = json.loads(info["slidetrack.dekf"])
    arch = json.loads(info.get("slidetrack.dekf.architecture", json.dumps(THESIS_ARCHITECTURE)))
    d = 1 if meta.get("state", "sliding") == "sliding" else 3
    tensors = {}
    for name, h in header.items():
        start, end = h["data_offsets"]
        tensors[name] = torch.from_numpy(np.frombuffer(data[start:end], dtype="<f4").reshape(h["shape"]).copy())
    zeros = lambda k: [[0.0] * k for _ in range(k)]
    model = Dekf(tensors["feature.input_mean"].shape[0], zeros(2 * d), zeros(d), arch, d)
    names = {
        "feature.input_mean": "input_mean",
        "feature.input_std": "input_std",
        "process_noise.cholesky": "lq",
        "measurement_noise.cholesky": "lr",
    }
    model.load_state_dict({names.get(k, k): v for k, v in tensors.items()})
    return model, meta


def check_golden(path):
    """Runs this script's own networks (Net) and filter (run_filter, the
    thesis's sliding filter: planar models have their networks checked only)
    on every model of the golden file (tests/golden/, docs/model-format.md)
    in float32, as it trains; prints JSON with the largest differences from
    the file's outputs (relative to max(|expected|, 1); the covariance to
    its largest element)."""
    golden = json.load(open(path))
    worst = lambda got, want, floor: float(
        (np.abs(got - want) / np.maximum(np.abs(want), floor)).max()
    )
    report = []
    with torch.no_grad():
        for entry in golden["models"]:
            model, meta = load(os.path.join(os.path.dirname(path), entry["file"]))
            network = 0.0
            for name, probes in entry["networks"].items():
                net = getattr(model, name)
                for probe in probes:
                    x = torch.tensor([probe["input"]], dtype=torch.float32)
                    jacobian = "jacobian" in probe
                    y = net(x, jacobian=jacobian)
                    got = [y[0][0], y[1][0]] if jacobian else [y[0]]
                    want = [probe["output"]] + ([probe["jacobian"]] if jacobian else [])
                    for g, w in zip(got, want):
                        network = max(network, worst(g.double().numpy().ravel(), np.array(w).ravel(), 1.0))
            row = {"name": entry["name"], "network": network, "mean": None, "covariance": None}
            if meta.get("state", "sliding") == "sliding":
                f = entry["filter"]
                m = torch.tensor([[np.nan if v is None else v for v in z] for z in f["measurements"]], dtype=torch.float32)
                valid = torch.isfinite(m).all(1).unsqueeze(1)
                meas = ((m - model.input_mean) / model.input_std).unsqueeze(1)
                P0 = torch.diag(torch.tensor(meta["p0_diag"], dtype=torch.float32)).unsqueeze(0)
                covs = []
                means = run_filter(model, torch.zeros(1, 2), P0, meas, valid, meta["dt_s"], len(m), covs)
                want_cov = np.array(f["cov"])
                row["mean"] = worst(means[:, 0].double().numpy(), np.array(f["mean"]), 1.0)
                row["covariance"] = max(
                    worst(c[0].double().numpy().ravel(), w, float(np.abs(w).max()))
                    for c, w in zip(covs, want_cov)
                )
            report.append(row)
    print(json.dumps({"torch": torch.__version__, "models": report}))


# ---------------------------------------------------------------- training


def windows_of(lengths, L):
    return [(i, t0) for i, n in enumerate(lengths) for t0 in range(0, max(n - L, 0), L)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check-golden", metavar="JSON", help="check the network and filter against the golden file and exit")
    ap.add_argument("--train", nargs="+")
    ap.add_argument("--out")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--schedule", default="2:5,4:5,8:5,16:5,32:5")
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--clip", type=float, default=0.0, help="global gradient-norm clip (0: none)")
    ap.add_argument("--lq-init", default="1,0,0,1", help="L_Q initial value, row-major")
    ap.add_argument("--lr-init", type=float, default=1.0, help="L_R initial value")
    ap.add_argument("--rate-hz", type=float, default=30.0)
    ap.add_argument("--cache", default="/tmp/dekf_torch_cache")
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    if args.check_golden:
        check_golden(args.check_golden)
        return
    if not (args.train and args.out):
        ap.error("--train and --out are required (or --check-golden)")

    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    data = [load_cached(p, args.cache, args.rate_hz) for p in args.train]
    rate, dec = data[0][2], data[0][3]
    dt = dec / rate
    raw = [d[0] for d in data]
    allm = np.concatenate(raw)
    mean, std = allm.mean(0), allm.std(0)
    std[std == 0] = 1.0
    C = allm.shape[1]
    lq = [float(v) for v in args.lq_init.split(",")]
    model = Dekf(C, [[lq[0], lq[1]], [lq[2], lq[3]]], [[args.lr_init]])
    model.input_mean.copy_(torch.tensor(mean, dtype=torch.float32))
    model.input_std.copy_(torch.tensor(std, dtype=torch.float32))
    meas = [torch.tensor((m - mean) / std, dtype=torch.float32) for m in raw]
    valid = [torch.tensor(np.all(np.isfinite(m), 1)) for m in raw]
    truth = [torch.tensor(d[1], dtype=torch.float32) for d in data]
    lengths = [len(t) for t in truth]
    opt = torch.optim.Adam(model.parameters(), lr=args.lr)
    p0 = torch.tensor([0.1, 0.1])
    schedule = [tuple(int(x) for x in s.split(":")) for s in args.schedule.split(",")]
    epochs = []
    started = time.time()
    for L, n_epochs in schedule:
        for _ in range(n_epochs):
            w = windows_of(lengths, L)
            order = rng.permutation(len(w))
            sq, n = np.zeros(2), 0
            for b0 in range(0, len(order), args.batch):
                batch = [w[j] for j in order[b0 : b0 + args.batch]]
                B = len(batch)
                gt0 = torch.stack([truth[i][t0] for i, t0 in batch])
                mu0 = gt0 + torch.randn(B, 2) * p0.sqrt()
                P0 = torch.diag(p0).expand(B, 2, 2)
                m = torch.stack([meas[i][t0 + 1 : t0 + L + 1] for i, t0 in batch], 1)
                v = torch.stack([valid[i][t0 + 1 : t0 + L + 1] for i, t0 in batch], 1)
                gt = torch.stack([truth[i][t0 + 1 : t0 + L + 1] for i, t0 in batch], 1)
                est = run_filter(model, mu0, P0, m, v, dt, L)
                err = (est - gt) ** 2
                loss = err.mean()
                opt.zero_grad()
                loss.backward()
                if args.clip > 0:
                    nn.utils.clip_grad_norm_(model.parameters(), args.clip)
                opt.step()
                sq += err.detach().sum((0, 1)).numpy()
                n += L * B
            rmse = np.sqrt(sq / n)
            epochs.append({"length": L, "rmse": rmse.tolist()})
            print(f"length {L}: RMSE {rmse[0]:.3f} cm, {rmse[1]:.3f} cm/s ({time.time() - started:.0f} s)", file=sys.stderr)
    meta = {
        "dt_s": dt,
        "decimation": dec,
        "tactile_rate_hz": rate,
        "channels": [f"{f}.{a}" for f in FINGERS for a in ("x", "y")],
        "measurement": "derivative",
        "derivative_filter": {"q_counts2_per_s3": 2.0e5, "r_counts2": 25.0, "initial_derivative_var": 1.0e4},
        "state_units": ["cm", "cm/s"],
        "p0_diag": [0.1, 0.1],
        "training": {"by": "scripts/dekf_torch_train.py", "args": vars(args), "epochs": epochs},
        "software_version": "torch-" + torch.__version__,
    }
    save(model, args.out, meta)
    print(json.dumps({"out": args.out, "seconds": time.time() - started, "final_rmse": epochs[-1]["rmse"]}))


if __name__ == "__main__":
    main()
