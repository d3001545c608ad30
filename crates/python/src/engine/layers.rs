//! [`StokesLayers`] (forces, stresslets and the pressure) as an
//! [`Engine`]: densities packed per source as `[f?, m?, n?]` (three values
//! each, those the request carries), values per target as `[velocity (3
//! or 12), pressure (1 or 4, with the request's pressure)]`.

use std::sync::Arc;

use ferrofmm_field::CacheStatus;
use ferrofmm_fmm::{
    BuildScheme, EvalTimings, FmmError, FmmSummary, ProgressFn, SetupTimings, StokesLayers,
    StokesValues,
};

use super::erased::{Engine, Evaluated, write_errors};
use super::floats::{Float, Floats};

/// Values per source of one vector: three per force, six per stresslet.
pub(super) fn values_per_source(forces: bool, stresslets: bool) -> usize {
    3 * usize::from(forces) + 6 * usize::from(stresslets)
}

/// One vector's packed densities as `(forces, (m, n))`.
type Unpacked<T> = (Option<Vec<T>>, Option<(Vec<T>, Vec<T>)>);

/// Split one vector's packed densities.
fn unpack<T: Copy>(packed: &[T], forces: bool, stresslets: bool) -> Unpacked<T> {
    let per = values_per_source(forces, stresslets);
    let column = |offset: usize| -> Vec<T> {
        packed
            .chunks_exact(per)
            .flat_map(|q| q[offset..offset + 3].iter().copied())
            .collect()
    };
    let at = 3 * usize::from(forces);
    (
        forces.then(|| column(0)),
        stresslets.then(|| (column(at), column(at + 3))),
    )
}

/// `[velocity, pressure]` per target.
fn interleave<T: Copy>(values: StokesValues<T>, gradient: bool) -> Vec<T> {
    let Some(pressure) = values.pressure else {
        return values.velocity;
    };
    let (wv, wp) = if gradient { (12, 4) } else { (3, 1) };
    values
        .velocity
        .chunks_exact(wv)
        .zip(pressure.chunks_exact(wp))
        .flat_map(|(u, p)| u.iter().chain(p).copied())
        .collect()
}

impl<T: Float, S: BuildScheme<T>> Engine for StokesLayers<T, S> {
    fn evaluate(&self, densities: Floats, n_vectors: usize) -> Result<Evaluated, FmmError> {
        let q = T::unwrap(densities);
        let r = self.request();
        let per = self.n_sources() * values_per_source(r.forces, r.stresslets);
        let mut values = Vec::new();
        let mut timings = EvalTimings::default();
        for one in q.chunks_exact(per.max(1)).take(n_vectors) {
            let (f, mn) = unpack(one, r.forces, r.stresslets);
            let mn = mn.as_ref().map(|(m, n)| (m.as_slice(), n.as_slice()));
            let e = StokesLayers::evaluate_timed(self, f.as_deref(), mn)?;
            values.extend(interleave(e.values, self.has_gradient()));
            timings.accumulate(&e.timings);
        }
        Ok(Evaluated {
            values: T::wrap(values),
            timings,
            energies: vec![None; n_vectors],
            verification: None,
        })
    }

    fn evaluate_verified(
        &mut self,
        densities: Floats,
        n_vectors: usize,
    ) -> Result<Evaluated, FmmError> {
        let q = T::unwrap(densities);
        let r = self.request();
        let per = self.n_sources() * values_per_source(r.forces, r.stresslets);
        let (f, mn) = unpack(&q[..per], r.forces, r.stresslets);
        let mn_ref = mn.as_ref().map(|(m, n)| (m.as_slice(), n.as_slice()));
        let first = StokesLayers::evaluate_verified(self, f.as_deref(), mn_ref)?;
        let verification = first.verification().cloned();
        let mut values = interleave(first.values, self.has_gradient());
        let mut timings = first.timings;
        if n_vectors > 1 {
            let rest = Engine::evaluate(self, T::wrap(q[per..].to_vec()), n_vectors - 1)?;
            values.extend(T::unwrap(rest.values));
            timings.accumulate(&rest.timings);
        }
        Ok(Evaluated {
            values: T::wrap(values),
            timings,
            energies: vec![None; n_vectors],
            verification,
        })
    }

    fn summary(&self) -> FmmSummary {
        self.stokes().summary()
    }

    fn set_progress(&mut self, progress: Option<Arc<ProgressFn>>) {
        StokesLayers::set_progress(self, progress);
    }

    fn setup_timings(&self) -> SetupTimings {
        *self.stokes().setup_timings()
    }

    fn n_sources(&self) -> usize {
        self.stokes().n_sources()
    }

    fn n_targets(&self) -> usize {
        self.stokes().n_targets()
    }

    fn cache_write_errors(&self) -> Vec<String> {
        let mut statuses = vec![
            self.stokes().operators().cache_status().clone(),
            self.stokes().m2l_scheme().cache_status(),
        ];
        if let Some(l) = self.laplace() {
            statuses.push(l.operators().cache_status().clone());
            statuses.push(l.m2l_scheme().cache_status());
        }
        write_errors(statuses)
    }

    fn cache_summary(&self) -> Option<String> {
        CacheStatus::summary(
            self.stokes().operators().cache_status(),
            &self.stokes().m2l_scheme().cache_status(),
        )
    }
}
