# A sweep from Python (docs/batch.md): the bundled Intel graph optimised with and without a robust
# kernel on a LocalCluster started for it, the table written to out/.
from probslam import batch

sweep = batch.Sweep([batch.RunGroup("optimize", ["bundled:intel_400.g2o"], {"kernel": ["none", "huber"]})])
if __name__ == "__main__":  # the local cluster's workers are spawned: guard the script
    rows = batch.run(sweep, directory="out", workers=2, progress=False)  # or batch.run("sweep.toml", client, "out")
    print(batch.summary(rows))
