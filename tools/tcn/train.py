#!/usr/bin/env python3
"""Trains the learned trajectory predictor (TileSplat sec. 3.3, App. C.2/C.3) on the windows that
`cargo run --release --example tcn_windows` exported, and writes the ONNX model Rust runs
(`crates/stream/src/learned/model.rs`) plus recorded inputs/outputs for the Rust parity test.

Usage: python tools/tcn/train.py WINDOWS_DIR OUT.onnx [--arch tcn|lstm] [--channels 64] [--every 1]
       [--blocks 4] [--hidden 64] [--epochs 40] [--parity PARITY.json] [--seed 7]

Reads only WINDOWS_DIR/{train,val}.* (the tuning set: no test scene or seed is ever exported).
Prints the per-epoch losses and the validation ADE/FDE table at 5..30 s.
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
from torch.nn.utils.parametrizations import weight_norm
from torch.nn.utils import parametrize

HIST, IN_C, FUT, OUT_C = 60, 6, 60, 5
STEP_S = 0.5
HORIZONS = [5, 10, 15, 20, 25, 30]


def load(dirname, name):
    meta = json.load(open(os.path.join(dirname, name + ".json")))
    n = meta["windows"]
    x = np.fromfile(os.path.join(dirname, name + ".x.f32"), dtype="<f4")
    y = np.fromfile(os.path.join(dirname, name + ".y.f32"), dtype="<f4")
    if x.size != n * HIST * IN_C or y.size != n * FUT * OUT_C:
        sys.exit(f"{dirname}/{name}: sizes do not match {name}.json ({n} windows)")
    return x.reshape(n, HIST, IN_C), y.reshape(n, FUT, OUT_C), np.array(meta["kind"]), meta["kinds"]


class CausalConv(nn.Module):
    """Dilated causal convolution: left padding (k-1)d (the Chomp1d of App. C.2), weight norm."""

    def __init__(self, cin, cout, k, d):
        super().__init__()
        self.pad = (k - 1) * d
        self.conv = weight_norm(nn.Conv1d(cin, cout, k, dilation=d, padding=self.pad))

    def forward(self, x):
        # Padded on both sides, the right side chomped: constant Conv pads and a constant Slice
        # in ONNX (a functional pad exports a computed Pad; crates/stream/src/learned/net.rs checks the
        # Conv's pads are the causal (k-1)d).
        return self.conv(x)[:, :, : -self.pad]


class Block(nn.Module):
    def __init__(self, cin, cout, k, d, dropout):
        super().__init__()
        self.c1 = CausalConv(cin, cout, k, d)
        self.c2 = CausalConv(cout, cout, k, d)
        self.drop = nn.Dropout(dropout)
        self.res = nn.Conv1d(cin, cout, 1) if cin != cout else None

    def forward(self, x):
        h = self.drop(F.relu(self.c1(x)))
        h = self.drop(F.relu(self.c2(h)))
        r = x if self.res is None else self.res(x)
        return F.relu(h + r)


class Net(nn.Module):
    """Encoder (TCN or LSTM) -> 2-layer LSTM decoder unrolled FUT steps -> mean, log-variance."""

    def __init__(self, arch, channels, blocks, hidden, xm, xs, ym, ys):
        super().__init__()
        for n, v in [("xm", xm), ("xs", xs), ("ym", ym), ("ys", ys)]:
            self.register_buffer(n, torch.tensor(v, dtype=torch.float32))
        self.arch = arch
        if arch == "tcn":
            layers, c = [], IN_C
            for b in range(blocks):
                layers.append(Block(c, channels, 3, 2 ** b, 0.15))
                c = channels
            self.enc = nn.Sequential(*layers)
        else:
            self.enc = nn.LSTM(IN_C, channels, num_layers=2, batch_first=True, dropout=0.1)
        self.dec = nn.LSTM(channels, hidden, num_layers=2, batch_first=True, dropout=0.1)
        self.mu = nn.Linear(hidden, OUT_C)
        self.lv = nn.Linear(hidden, OUT_C)

    def forward(self, x):  # x: [B, HIST, IN_C] raw features
        z = (x - self.xm) / self.xs
        if self.arch == "tcn":
            ctx = self.enc(z.transpose(1, 2))[:, :, -1]
        else:
            ctx = self.enc(z)[0][:, -1, :]
        seq = ctx.unsqueeze(1).expand(-1, FUT, -1)
        h = self.dec(seq)[0]
        mean = self.mu(h) * self.ys + self.ym
        logvar = self.lv(h) + 2.0 * torch.log(self.ys)
        return mean, logvar


def nll(mean, logvar, y):
    """Gaussian NLL of eq. 10 (mean over steps and state channels)."""
    return (0.5 * logvar + 0.5 * (y - mean) ** 2 * torch.exp(-logvar)).mean()


def errors(mean, y):
    """Mean 3-D position error per future step."""
    return torch.linalg.norm(mean[..., :3] - y[..., :3], dim=-1).mean(0)


def table(err):
    ade = [float(err[: int(h / STEP_S)].mean()) for h in HORIZONS]
    fde = [float(err[int(h / STEP_S) - 1]) for h in HORIZONS]
    return ade, fde


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("windows")
    ap.add_argument("out")
    ap.add_argument("--arch", choices=["tcn", "lstm"], default="tcn")
    ap.add_argument("--channels", type=int, default=64)
    ap.add_argument("--blocks", type=int, default=4)
    ap.add_argument("--hidden", type=int, default=64)
    ap.add_argument("--epochs", type=int, default=40)
    ap.add_argument("--patience", type=int, default=6)
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--every", type=int, default=1, help="keep every N-th training window")
    ap.add_argument("--parity")
    a = ap.parse_args()
    torch.manual_seed(a.seed)
    np.random.seed(a.seed)
    torch.set_num_threads(a.threads)
    xt, yt, _, _ = load(a.windows, "train")
    xt, yt = xt[:: a.every], yt[:: a.every]
    xv, yv, kv, kinds = load(a.windows, "val")
    print(f"train {len(xt)} windows, val {len(xv)} windows")
    xm, xs = xt.reshape(-1, IN_C).mean(0), xt.reshape(-1, IN_C).std(0) + 1e-3
    ym, ys = yt.reshape(-1, OUT_C).mean(0), yt.reshape(-1, OUT_C).std(0) + 1e-3
    net = Net(a.arch, a.channels, a.blocks, a.hidden, xm, xs, ym, ys)
    params = sum(p.numel() for p in net.parameters())
    print(f"{a.arch}: channels {a.channels}, blocks {a.blocks}, hidden {a.hidden}, {params} parameters")
    Xt, Yt, Xv, Yv = map(torch.from_numpy, (xt, yt, xv, yv))
    steps = a.epochs * math.ceil(len(Xt) / a.batch)
    opt = torch.optim.AdamW(net.parameters(), lr=1e-4, weight_decay=1e-5)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=1e-3, total_steps=steps, pct_start=0.3,
                                                div_factor=10.0)
    best, best_state, bad, t0 = float("inf"), None, 0, time.time()
    gen = torch.Generator().manual_seed(a.seed)
    for ep in range(a.epochs):
        net.train()
        perm = torch.randperm(len(Xt), generator=gen)
        tot = 0.0
        for i in range(0, len(Xt), a.batch):
            idx = perm[i : i + a.batch]
            m, lv = net(Xt[idx])
            loss = nll(m, lv, Yt[idx])
            opt.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(net.parameters(), 1.0)
            opt.step()
            sched.step()
            tot += loss.item() * len(idx)
        net.eval()
        with torch.no_grad():
            m, lv = net(Xv)
            vl = float(nll(m, lv, Yv))
            ade5 = table(errors(m, Yv))[0][0]
        print(f"epoch {ep + 1}: train nll {tot / len(Xt):.4f}, val nll {vl:.4f}, val ADE@5s {ade5:.3f} m, "
              f"{time.time() - t0:.0f} s", flush=True)
        if vl < best - 1e-4:
            best, bad = vl, 0
            best_state = {k: v.clone() for k, v in net.state_dict().items()}
        else:
            bad += 1
            if bad >= a.patience:
                print(f"early stop after epoch {ep + 1}")
                break
    train_s = time.time() - t0
    net.load_state_dict(best_state)
    net.eval()
    with torch.no_grad():
        m, lv = net(Xv)
    print(f"trained in {train_s:.0f} s; best val nll {best:.4f}")
    torch.save(best_state, a.out + ".pt")
    print("val ADE/FDE (m) at " + ", ".join(f"{h} s" for h in HORIZONS))
    for k, kind in [(None, "all")] + list(enumerate(kinds)):
        sel = slice(None) if k is None else torch.from_numpy(kv == k)
        if k is not None and int(sel.sum()) == 0:
            continue
        ade, fde = table(errors(m[sel], Yv[sel]))
        print(f"  {kind:12s} ADE " + " ".join(f"{v:7.2f}" for v in ade) + "   FDE " + " ".join(f"{v:7.2f}" for v in fde))
    # Export: weight norm folded into plain weights, dropout off.
    for mod in net.modules():
        if isinstance(mod, nn.Conv1d) and parametrize.is_parametrized(mod, "weight"):
            parametrize.remove_parametrizations(mod, "weight")
    dummy = torch.zeros(1, HIST, IN_C)
    torch.onnx.export(net, dummy, a.out, input_names=["history"], output_names=["mean", "logvar"],
                      opset_version=17, dynamo=False)
    print(f"wrote {a.out} ({os.path.getsize(a.out)} bytes)")
    if a.parity:
        pick = [0, len(Xv) // 3, 2 * len(Xv) // 3]
        with torch.no_grad():
            pm, plv = net(Xv[pick])
        rec = {"inputs": Xv[pick].reshape(len(pick), -1).tolist(),
               "mean": pm.reshape(len(pick), -1).tolist(),
               "logvar": plv.reshape(len(pick), -1).tolist(),
               "torch": torch.__version__}
        json.dump(rec, open(a.parity, "w"))
        print(f"wrote {a.parity}")


if __name__ == "__main__":
    main()
