//! Smoke test: libtorch links, loads without LD_LIBRARY_PATH, and a gradient step on a small
//! MLP updates every parameter and lowers the loss.

use tch::nn::{self, Module, OptimizerConfig};
use tch::{Device, Kind, Tensor};

#[test]
fn a_gradient_step_reaches_every_parameter_and_lowers_the_loss() {
    tch::manual_seed(7);
    let vs = nn::VarStore::new(Device::Cpu);
    let root = vs.root();
    let net = nn::seq()
        .add(nn::linear(&root / "l1", 25, 64, Default::default()))
        .add_fn(|x| x.relu())
        .add(nn::linear(&root / "l2", 64, 64, Default::default()))
        .add_fn(|x| x.relu())
        .add(nn::linear(&root / "l3", 64, 2, Default::default()));
    let mut opt = nn::Adam::default().build(&vs, 1e-2).unwrap();

    let x = Tensor::randn([256, 25], (Kind::Float, Device::Cpu));
    // A learnable target: a fixed linear map of the input.
    let w = Tensor::randn([25, 2], (Kind::Float, Device::Cpu));
    let y = x.matmul(&w);

    let loss_of = |net: &nn::Sequential| (net.forward(&x) - &y).square().mean(Kind::Float);
    let before = loss_of(&net).double_value(&[]);

    opt.zero_grad();
    let loss = loss_of(&net);
    loss.backward();
    for (name, param) in vs.variables() {
        let grad = param.grad();
        assert!(grad.defined(), "parameter {name} received no gradient");
        assert!(
            grad.abs().sum(Kind::Float).double_value(&[]) > 0.0,
            "parameter {name} has an all-zero gradient"
        );
    }
    opt.step();
    for _ in 0..50 {
        opt.backward_step(&loss_of(&net));
    }
    let after = loss_of(&net).double_value(&[]);
    assert!(
        after < before * 0.5,
        "loss did not fall: {before} -> {after}"
    );
}
