# The golden cases: every command on small fixed-seed inputs (sourced by
# scripts/golden.sh, which defines `run NAME -- ARGS...`). Each case runs
# `bootsurf ARGS... --json` in one scratch directory; its JSON summary (less
# timings, thread count and version) is kept as json/NAME.json and every file
# the cases write is pinned by its sha256 in SHA256SUMS.
#
# Add cases at the end; a case's inputs must be written by an earlier case (or
# be box.off, copied in first). Keep the whole list quick (seconds, not minutes).

# generate: the four shapes, both samplings, ascii and binary
run gen_cube -- generate cube -n 3000 -o cube.ply
run gen_sphere -- generate sphere -n 2000 -o sphere.ply
run gen_torus -- generate torus -n 2000 --sampling random --seed 4 -o torus.ply
run gen_plane -- generate plane -n 1000 --ascii -o plane.ply

# noise: gaussian in h, uniform in h, gaussian by the diagonal
run noise_cube -- noise cube.ply --level 0.5 -o cube_noisy.ply
run noise_sphere -- noise sphere.ply --level 0.5 --model uniform --seed 3 -o sphere_noisy.ply
run noise_torus -- noise torus.ply --sigma-diag 0.006 -o torus_noisy.ply
run noise_plane -- noise plane.ply --level 0.3 -o plane_noisy.ply

# sample: a box mesh with sharp edges, by area and its vertices
run sample_area -- sample box.off -n 3000 -o box.ply
run sample_vertices -- sample box.off --ascii -o box_vertices.ply
run noise_box -- noise box.ply --level 0.5 --model uniform -o box_noisy.ply

run info -- info cube_noisy.ply

# error (chapter 4): the estimators, two degrees and gamma modes, tiled
run error_cube -- error cube_noisy.ply -k 30 -B 10 -o cube_err.ply
run error_sphere -- error sphere_noisy.ply -k 20 -d 2 -B 8 --gamma mean --pca-center point -o sphere_err.ply
run error_tiled -- error cube_noisy.ply -k 30 -B 10 --tile-points 1000 -o cube_err_tiled.ply
run error_test_sample -- error plane_noisy.ply -k 25 -d 1 -B 6 --test-sample plane_noisy.ply -o plane_err.ply

# normals (chapter 5): bootstrap, test error, K and degree selection, smoothing, orientation, tiled
run normals_cube -- normals cube_noisy.ply -k 20 -B 10 -o cube_n.ply
run normals_single -- normals box_noisy.ply -k 20 -B 0 --ascii -o box_n.ply
run normals_test_error -- normals cube_noisy.ply -k 20 -B 10 --test-error -o cube_nte.ply
run normals_select_k -- normals cube_noisy.ply --select-k 10:30:10 -B 6 --curve cube_curve.csv --truth cube.ply -o cube_nsel.ply
run normals_select_degree -- normals sphere_noisy.ply --fit poly -d 2 --select-k 10:30:10 --select-degree 1,2 -B 6 -o sphere_nsd.ply
run normals_smooth_orient -- normals torus_noisy.ply -k 20 -B 10 --smooth-iterations 3 --orient mst -o torus_n.ply
run normals_tiled -- normals cube_noisy.ply -k 20 -B 10 --tile-points 1000 -o cube_n_tiled.ply

# smooth (chapter 6): every method, tiled where supported
run smooth_default -- smooth cube_noisy.ply -o cube_sm.ply
run smooth_naive -- smooth cube_noisy.ply --method naive -o cube_sm_naive.ply
run smooth_multipass -- smooth box_noisy.ply --method multipass -o box_sm_mp.ply
run smooth_tiled -- smooth cube_noisy.ply --tile-points 1000 -o cube_sm_tiled.ply

# features (chapter 7): distance map and variance threshold, tiled
run features_distance -- features cube_noisy.ply --method distance -o cube_fd.ply
run features_variance -- features cube_noisy.ply --method variance -o cube_fv.ply
run features_box -- features box_noisy.ply --method distance -o box_fd.ply
run features_tiled -- features cube_noisy.ply --method distance --tile-points 1000 -o cube_fd_tiled.ply

# eval against the truth: normals with a split, features, positions on a mesh
run eval_normals -- eval cube_n.ply --truth cube.ply --split normal_var:0.85
run eval_features -- eval cube_fd.ply --truth cube.ply
run eval_smooth -- eval cube_sm.ply --truth cube.ply
run eval_box -- eval box_n.ply --truth box.ply --surface box.off

# pictures
run render_field -- render cube_err.ply --field err_632plus --size 160x120 -o cube_err.png
run render_views -- render torus_n.ply --views 4 --size 160x120 -o torus_views.png
run histogram -- histogram cube_err.ply --field err_632plus --threshold 0.05 --log --size 200x120 -o cube_hist.png
run compare -- compare cube_sm.ply cube_sm_naive.ply --field err_632plus --size 120x120 -o cube_compare.png

# convert: every format bootsurf writes, with fields (docs/formats.md)
run convert_pcd_ascii -- convert cube_err.ply --ascii cube_err_a.pcd
run convert_pcd_binary -- convert cube_err.ply cube_err_b.pcd
run convert_las14 -- convert cube_err.ply cube_err.las
run convert_las12 -- convert cube_n.ply --las-version 1.2 cube_n12.las
run convert_csv -- convert cube_err.ply cube_err.csv
run convert_back -- convert cube_err.las cube_err_las.ply
run convert_cloudcompare -- convert cube_err.ply --ply-names cloudcompare --float32 cube_err_cc.ply

# the MSE selection rule (docs/normals.md)
run normals_select_mse -- normals cube_noisy.ply --select-k 10:30:10 --select-rule mse -B 0 -o cube_nmse.ply
