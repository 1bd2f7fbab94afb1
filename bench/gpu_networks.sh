#!/usr/bin/env bash
# Issue 19 on a lent GPU (bench/README.md, "Trained on a GPU"): the many-track campaign of
# the shipped networks in CONDITIONS (default straight; 2048 samples, design seed 0: a
# campaign of some conditions has the samples and tracks of the three-condition one, so the
# same held-out tracks), its nominal twins and the straight condition's perturbed twins made
# on the machine's CPU cores, then at once on the GPU, within one wall-clock budget:
#   -gpu   the study's CNN-GRU of each condition continued from the shipped set's network
#          (its features and normalisation kept) in batches of 256 chunks;
#   -gpuw  a wider sequence network on tangent, from scratch (GRU 128,64,32, dense 64,32,16);
# then each scored on the held-out runs (Table 7) and the parameter gains on tangent
# (bench/pair_gains.py) of the shipped network and both new ones. What comes back lies in
# OUT_DIR: networks.tgz (the bundles without their checkpoints), logs.tgz and the JSON.
#
#   bash bench/gpu_networks.sh OUT_DIR [BUDGET_S] [SAMPLES]
#
# BUDGET_S (default 540) is the whole script's: the trainings get what the campaign leaves,
# less RESERVE_S (150) for scoring. SAMPLES=32 with DEVICE=cpu BATCHES=2 CHUNKS=8 is a smoke
# run of the same steps on a CPU (about 2 min); PYTHON names the interpreter (python3),
# RUN_DIR the campaign's folder (/tmp/gpu-tracks). The lent machine's python3 (3.12, torch
# with CUDA, numba) had no pydantic on 2026-11-28: its wheels (pydantic, pydantic_core,
# annotated_types, typing_inspection, typing_extensions, cp312 manylinux) were carried and
# installed with --target before this script ran. Tried on 2026-11-28 (stop 46): the
# campaign, its curve then simulated one layout at a time, took 508 s of the lease
# (bench/README.md).
set -euo pipefail
out=${1:?OUT_DIR}
budget=${2:-540}
samples=${3:-2048}
start=$(date +%s)
run=${RUN_DIR:-/tmp/gpu-tracks}
log=$out/logs
mkdir -p "$log"
export PYTHONUNBUFFERED=1 PYTHONPATH=$PWD/src${PYTHONPATH:+:$PYTHONPATH}
py=${PYTHON:-python3}
conditions=${CONDITIONS:-straight}
# the perturbed twins and the wider network are the tangent's
case ",$conditions," in *,straight,*) ;; *) echo "CONDITIONS must hold straight"; exit 2 ;; esac
st="$py bench/surrogate_tracks.py --run $run --samples $samples --conditions $conditions \
--models '' --nominal --nominal-kinds cnn-gru-seq"
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader || true
$py -c "import torch; print('torch', torch.__version__, 'cuda', torch.cuda.is_available())"

# 1. the campaign, nominal twins of every condition, perturbed twins on tangent (CPU)
eval "$st --prepare-only" 2>&1 | tee "$log/campaign.txt"
eval "$st --prepare-only --train-conditions straight --pair-weight 1 --pair-twins 1 --tag=-p" \
    2>&1 | tee -a "$log/campaign.txt"
for c in ${conditions//,/ }; do
    mkdir -p "$run/surrogates/ship"
    cp -r "src/railsusp/data/networks/c80_k6/$c" "$run/surrogates/ship/"
done

# 2. the trainings, concurrently on the GPU, until the budget less a reserve for scoring
reserve=${RESERVE_S:-150}
left=$(( budget - ($(date +%s) - start) - reserve ))
if (( left < 30 )); then echo "no time left to train ($left s)"; exit 1; fi
minutes=$($py -c "print($left / 60)")
echo "training for $minutes min"
common="--device ${DEVICE:-cuda} --chunks-per-batch ${CHUNKS:-256} --batches-per-epoch ${BATCHES:-100} --max-minutes $minutes --patience 30 \
--train-threads 2 --threads 2 --repeats 1"
pids=()
for c in ${conditions//,/ }; do
    eval "$st $common --train-conditions $c --init-from ship --init-inputs --tag=-gpu \
        --epochs 2000 --fine-tune-epochs 500 --fine-tune-lr-factor 0.2 --learning-rate 1e-3 \
        --out $out/tracks-gpu-$c.json" > "$log/gpu-$c.txt" 2>&1 &
    pids+=($!)
done
eval "$st $common --train-conditions straight --rnn-hidden 128,64,32 --dense 64,32,16 \
    --tag=-gpuw --epochs 2000 --fine-tune-epochs 500 --fine-tune-lr-factor 0.2 \
    --learning-rate 2e-3 --out $out/tracks-gpuw-straight.json" > "$log/gpuw-straight.txt" 2>&1 &
pids+=($!)
fail=0
for p in "${pids[@]}"; do wait "$p" || fail=1; done
tail -n 25 "$log"/gpu*.txt

# 3. the parameter gains on tangent: shipped, continued, wider
$py bench/pair_gains.py "$run" --kinds ship,cnn-gru-seq-nominal-gpu,cnn-gru-seq-nominal-gpuw \
    --threads 4 --out "$out/pair_gains-gpu.json" 2>&1 | tee "$log/pair_gains.txt" || fail=1
tar -C "$run" --exclude=checkpoint.pt -czf "$out/networks.tgz" \
    surrogates/cnn-gru-seq-nominal-gpu surrogates/cnn-gru-seq-nominal-gpuw || fail=1
tar -C "$out" -czf "$out/logs.tgz" logs && rm -r "$log"
echo "done in $(( $(date +%s) - start )) s, failures: $fail"
exit $fail
